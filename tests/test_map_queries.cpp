// Ray casts, box and occupied-cell queries against brute-force references: every cell a ray's
// segment meets found by a slab test per cell, every cell of a region looped over; one real map
// (sim_structured) against liboctomap's OcTree::castRay on the .bt bgkmap writes; the CLI.
// Tolerance: 1e-9 m along a ray (a cell met for less than that is "touched": at an exact tie the
// DDA may stop there or not).
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "bgkmap/dist/partition.hpp"
#include "bgkmap/dist/shards.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/map/map_queries.hpp"
#include "bgkmap/mapper.hpp"
#include "core/grid_traversal.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

constexpr double kTouch = 1e-9;  // m: a cell met for less than this along the ray is only touched

// ---- random maps ------------------------------------------------------------------------------

// Blocks of 4^3 cells in [-3, 2]^3 block keys, 60 % of them present; their cells at the prior
// (35 %), free (25 %), occupied (15 %) or unknown with evidence (25 %: mean 0.5). A planar map's
// blocks hold evidence in its layer only.
BgkMap random_map(uint32_t seed, double resolution, bool planar) {
  BuildParams params;
  params.grid.resolution_m = resolution;
  params.grid.block_depth = 3;
  if (planar) params.set_planar(0.3);
  BgkMap map(params);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> uniform(0, 1);
  const int n = map.cells_per_block();
  for (int32_t z = -3; z <= 2; ++z)
    for (int32_t y = -3; y <= 2; ++y)
      for (int32_t x = -3; x <= 2; ++x) {
        if (planar && z != map.layer_block_z()) continue;
        if (uniform(rng) > 0.6) continue;
        const BlockKey key{x, y, z};
        Cell* cells = map.block_cells(map.ensure_slot(key));
        for (int local = 0; local < n; ++local) {
          if (planar && map.grid().cell_at(key, local).z != params.planar_layer()) continue;
          const double u = uniform(rng);
          if (u < 0.35) continue;
          cells[local] = u < 0.6 ? Cell{0.1f, 10.f} : u < 0.75 ? Cell{10.f, 0.1f} : Cell{2.f, 2.f};
        }
      }
  return map;
}

CellState state_at(const BgkMap& map, const CellIndex& c) {
  const Vec3d centre = map.grid().cell_center_d(c);
  return map.query(centre.x, centre.y, centre.z).state(map.params().classify);
}

// ---- the slab-test reference --------------------------------------------------------------------

struct MetCell {
  CellIndex cell;
  double t_in = 0, t_out = 0;  // where origin + t u (t in [0, length]) is inside the closed cell
  // The ray's points lie in the cell (half-open, as Grid::cell_of) for more than kTouch.
  bool passed = false;
};

// Every cell whose closed box meets the segment, by a slab test on each cell near it, ordered by
// where the ray meets it.
std::vector<MetCell> cells_met(const Grid& grid, const Vec3d& o, const Vec3d& u, double length) {
  const double r = grid.resolution();
  const double a[3] = {o.x, o.y, o.z}, d[3] = {u.x, u.y, u.z};
  int32_t lo[3], hi[3];
  for (int i = 0; i < 3; ++i) {
    const double end = a[i] + length * d[i];
    lo[i] = static_cast<int32_t>(std::floor(std::min(a[i], end) / r)) - 1;
    hi[i] = static_cast<int32_t>(std::floor(std::max(a[i], end) / r)) + 1;
  }
  std::vector<MetCell> met;
  for (int32_t z = lo[2]; z <= hi[2]; ++z)
    for (int32_t y = lo[1]; y <= hi[1]; ++y)
      for (int32_t x = lo[0]; x <= hi[0]; ++x) {
        const int32_t c[3] = {x, y, z};
        double t0 = 0, t1 = length;
        bool inside_flat = true;  // on the axes the ray does not move along, half-open
        for (int i = 0; i < 3 && t0 <= t1; ++i) {
          const double low = c[i] * r, high = (c[i] + 1) * r;
          if (d[i] == 0) {
            if (a[i] < low || a[i] > high) t0 = 1, t1 = 0;
            inside_flat = inside_flat && std::floor(a[i] / r) == c[i];  // Grid::cell_of's cell
            continue;
          }
          double ta = (low - a[i]) / d[i], tb = (high - a[i]) / d[i];
          if (ta > tb) std::swap(ta, tb);
          t0 = std::max(t0, ta);
          t1 = std::min(t1, tb);
        }
        if (t0 > t1 + kTouch) continue;
        met.push_back({CellIndex{x, y, z}, t0, t1, inside_flat && t1 - t0 > kTouch});
      }
  std::sort(met.begin(), met.end(), [](const MetCell& p, const MetCell& q) { return p.t_in < q.t_in; });
  return met;
}

const MetCell* find_met(const std::vector<MetCell>& met, const CellIndex& c) {
  for (const MetCell& m : met)
    if (m.cell == c) return &m;
  return nullptr;
}

// The box of the map's blocks, and where a ray leaves it (the edge of kMapEnd).
double exit_of_blocks(const BgkMap& map, const Vec3d& o, const Vec3d& u) {
  const double size = map.grid().block_size();
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (uint32_t s = 0; s < map.block_count(); ++s) {
    const BlockKey& k = map.key_of_slot(s);
    const int32_t key[3] = {k.x, k.y, k.z};
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], key[i] * size), hi[i] = std::max(hi[i], (key[i] + 1) * size);
  }
  const double a[3] = {o.x, o.y, o.z}, d[3] = {u.x, u.y, u.z};
  double t0 = 0, t1 = 1e300;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (a[i] < lo[i] || a[i] > hi[i]) return 0;
      continue;
    }
    double ta = (lo[i] - a[i]) / d[i], tb = (hi[i] - a[i]) / d[i];
    if (ta > tb) std::swap(ta, tb);
    t0 = std::max(t0, ta);
    t1 = std::min(t1, tb);
  }
  return t0 <= t1 ? t1 : 0;
}

Vec3d unit(const Vec3d& d) {
  const double l = std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z);
  return {d.x / l, d.y / l, d.z / l};
}

// Checks one cast against the reference walk of the cells met; returns true when the two stopped
// at different cells of an exact tie (the cast's cell only touched, no later than the reference's).
bool expect_cast_matches_reference(const BgkMap& map, const Vec3d& origin_in, const Vec3d& direction, double max_range,
                                   UnknownPolicy policy, const RayCast& got, const std::string& what) {
  const bool planar = map.params().preprocess.planar;
  const Vec3d o{origin_in.x, origin_in.y, planar ? map.params().preprocess.plane_z_m : origin_in.z};
  const Vec3d u = unit({direction.x, direction.y, planar ? 0.0 : direction.z});
  const double limit = max_range == 0 ? 8.0 : max_range;  // 8 m: from any test origin, beyond every block
  const std::vector<MetCell> met = cells_met(map.grid(), o, u, limit);
  const auto stops = [&](const CellIndex& c) {
    const CellState s = state_at(map, c);
    return s == CellState::kOccupied || (s == CellState::kUnknown && policy == UnknownPolicy::kStop);
  };
  const MetCell* expected = nullptr;
  for (const MetCell& m : met)
    if (m.passed && stops(m.cell)) {
      expected = &m;
      break;
    }
  const bool got_stopped_at_cell = got.stop == RayStop::kOccupied || got.stop == RayStop::kUnknown;
  if (got_stopped_at_cell && (!expected || !(got.cell == expected->cell))) {
    // Only a cell the ray touches at a tie, no later than the reference's stop, may stand in for it.
    const MetCell* touched = find_met(met, got.cell);
    EXPECT_TRUE(touched && !touched->passed && stops(got.cell)) << what;
    if (touched && expected) {
      EXPECT_LE(touched->t_in, expected->t_in + kTouch) << what;
    }
    if (touched) {
      EXPECT_NEAR(got.distance, touched->t_in, kTouch) << what;
    }
    return true;
  }
  if (expected) {
    EXPECT_EQ(got.stop, state_at(map, expected->cell) == CellState::kOccupied ? RayStop::kOccupied : RayStop::kUnknown)
        << what;
    EXPECT_NEAR(got.distance, expected->t_in, kTouch) << what;
    EXPECT_TRUE(got.hit() == (got.stop == RayStop::kOccupied)) << what;
  } else if (max_range != 0) {
    EXPECT_EQ(got.stop, RayStop::kMaxRange) << what;
    EXPECT_EQ(got.distance, max_range) << what;
    const MetCell* end = find_met(met, got.cell);
    EXPECT_TRUE(end && end->t_in <= max_range + kTouch && end->t_out >= max_range - kTouch) << what;
  } else {
    EXPECT_EQ(got.stop, RayStop::kMapEnd) << what;
    const double edge = exit_of_blocks(map, o, u);
    EXPECT_NEAR(got.distance, edge, kTouch) << what;
    const MetCell* end = find_met(met, got.cell);
    EXPECT_TRUE(end && end->t_in <= edge + kTouch && end->t_out >= edge - kTouch) << what;
  }
  const Vec3d c = map.grid().cell_center_d(got.cell);
  EXPECT_EQ(got.center.x, c.x);
  EXPECT_EQ(got.center.y, c.y);
  EXPECT_EQ(got.center.z, c.z);
  EXPECT_EQ(got.state, state_at(map, got.cell)) << what;
  return false;
}

std::string describe(const Vec3d& o, const Vec3d& d, double range, UnknownPolicy policy) {
  std::ostringstream s;
  s.precision(17);
  s << "ray " << o.x << " " << o.y << " " << o.z << " dir " << d.x << " " << d.y << " " << d.z << " range " << range
    << " " << to_string(policy);
  return s.str();
}

struct RaySet {
  std::vector<Vec3d> origins, directions;
  std::vector<double> ranges;
  void add(const Vec3d& o, const Vec3d& d, double range) {
    origins.push_back(o), directions.push_back(d), ranges.push_back(range);
  }
};

// Random rays in and around the map, axis-aligned rays (origins on faces among them), and rays
// through cell corners and along cell edges; both signs of every direction.
RaySet test_rays(uint32_t seed, double r) {
  RaySet rays;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> coord(-2.2, 1.8), comp(-1, 1), range(0.05, 4);
  std::uniform_int_distribution<int> cell(-16, 12), pick(0, 3);
  const auto some_range = [&] { return pick(rng) == 0 ? 0.0 : range(rng); };
  for (int i = 0; i < 400; ++i) rays.add({coord(rng), coord(rng), coord(rng)}, {comp(rng), comp(rng), comp(rng)}, some_range());
  for (int i = 0; i < 60; ++i)
    for (int axis = 0; axis < 3; ++axis)
      for (double sign : {1.0, -1.0}) {
        Vec3d o{coord(rng), coord(rng), coord(rng)};
        if (i % 3 == 0) o = {cell(rng) * r, cell(rng) * r, cell(rng) * r};  // on faces, edges and corners
        Vec3d d{0, 0, 0};
        (axis == 0 ? d.x : axis == 1 ? d.y : d.z) = sign;
        rays.add(o, d, some_range());
      }
  for (int i = 0; i < 150; ++i) {
    const Vec3d corner{cell(rng) * r, cell(rng) * r, cell(rng) * r};
    const Vec3d d{pick(rng) % 2 ? 1.0 : -1.0, pick(rng) % 2 ? 1.0 : -1.0, pick(rng) == 0 ? 0.0 : (pick(rng) % 2 ? 1.0 : -1.0)};
    rays.add(corner, d, some_range());
  }
  return rays;
}

class RayCastReference : public ::testing::TestWithParam<double> {};

TEST_P(RayCastReference, FirstStoppingCellIsTheSlabReferencesOnRandomMaps) {
  const double r = GetParam();
  for (bool planar : {false, true}) {
    const BgkMap map = random_map(planar ? 21 : 7, r, planar);
    const RayCaster caster(map);
    const RaySet rays = test_rays(planar ? 5 : 3, r);
    size_t ties = 0, hits = 0, unknown = 0, max_range = 0, map_end = 0;
    for (UnknownPolicy policy : {UnknownPolicy::kStop, UnknownPolicy::kPass})
      for (size_t i = 0; i < rays.origins.size(); ++i) {
        if (planar && rays.directions[i].x == 0 && rays.directions[i].y == 0) continue;  // refused: below
        const RayCast got = caster.cast(rays.origins[i], rays.directions[i], rays.ranges[i], policy);
        const std::string what = describe(rays.origins[i], rays.directions[i], rays.ranges[i], policy);
        const bool tie =
            expect_cast_matches_reference(map, rays.origins[i], rays.directions[i], rays.ranges[i], policy, got, what);
        ties += tie;
        if (tie && i < 400) ADD_FAILURE() << "a random ray met an exact tie: " << what;
        hits += got.stop == RayStop::kOccupied;
        unknown += got.stop == RayStop::kUnknown;
        max_range += got.stop == RayStop::kMaxRange;
        map_end += got.stop == RayStop::kMapEnd;
        EXPECT_EQ(got.center.z, planar ? map.params().preprocess.plane_z_m : got.center.z);
      }
    // Every way of ending is exercised.
    EXPECT_GT(hits, 100u);
    EXPECT_GT(unknown, 100u);
    EXPECT_GT(max_range, 20u);
    EXPECT_GT(map_end, 5u);
    std::printf("resolution %g%s: %zu hits, %zu unknown, %zu max range, %zu map end, %zu exact ties\n", r,
                planar ? " planar" : "", hits, unknown, max_range, map_end, ties);
  }
}

// 0.125 m: corners are exact binary fractions, so the corner rays cross exact ties; 0.1 m: not.
INSTANTIATE_TEST_SUITE_P(Resolutions, RayCastReference, ::testing::Values(0.125, 0.1));

TEST(RayCast, StartsInsideAnOccupiedCellAtDistanceZero) {
  const BgkMap map = random_map(7, 0.1, false);
  bool found = false;
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) {
    if (found || p.state(map.params().classify) != CellState::kOccupied) return;
    found = true;
    const Vec3d centre = map.grid().cell_center_d(c);
    const Vec3d inside{centre.x + 0.03, centre.y - 0.02, centre.z + 0.045};
    for (UnknownPolicy policy : {UnknownPolicy::kStop, UnknownPolicy::kPass}) {
      const RayCast got = cast_ray(map, inside, {-0.3, 1, 0.2}, 2.0, policy);
      EXPECT_TRUE(got.hit());
      EXPECT_EQ(got.cell, c);
      EXPECT_EQ(got.distance, 0.0);
    }
  });
  EXPECT_TRUE(found);
}

// A planar map casts in its plane: the origin's height and the direction's z do not matter, and
// distances are in the plane.
TEST(RayCast, PlanarMapCastsInItsPlane) {
  const BgkMap map = random_map(21, 0.1, true);
  const RayCaster caster(map);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> coord(-2, 1.5), comp(-1, 1);
  for (int i = 0; i < 200; ++i) {
    const double ox = coord(rng), oy = coord(rng), dx = comp(rng), dy = comp(rng);
    const RayCast flat = caster.cast({ox, oy, 0.3}, {dx, dy, 0}, 3.0, UnknownPolicy::kPass);
    const RayCast tilted = caster.cast({ox, oy, 7.5}, {dx, dy, comp(rng) * 10}, 3.0, UnknownPolicy::kPass);
    EXPECT_EQ(flat.cell, tilted.cell);
    EXPECT_EQ(flat.distance, tilted.distance);
    EXPECT_EQ(flat.stop, tilted.stop);
    EXPECT_EQ(flat.cell.z, map.params().planar_layer());
  }
  EXPECT_THROW(caster.cast({0, 0, 0}, {0, 0, 1}, 1, UnknownPolicy::kStop), std::invalid_argument);
}

TEST(RayCast, RefusesRaysThatHaveNoMeaning) {
  const BgkMap map = random_map(7, 0.1, false);
  const RayCaster caster(map);
  const double nan = std::nan("");
  const auto refused = [&](const Vec3d& o, const Vec3d& d, double range, const std::string& message) {
    try {
      caster.cast(o, d, range, UnknownPolicy::kStop);
      ADD_FAILURE() << "not refused: " << message;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), message);
    }
  };
  refused({0, 0, 0}, {0, 0, 0}, 1, "the ray's direction is zero");
  refused({nan, 0, 0}, {1, 0, 0}, 1, "the ray's origin is not finite");
  refused({0, 0, 0}, {1, nan, 0}, 1, "the ray's direction is not finite");
  refused({2e6, 0, 0}, {1, 0, 0}, 1, "the ray's origin lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
  refused({0, 0, 0}, {1, 0, 0}, -1, "max range -1 is not a length (0: no limit)");
  refused({0, 0, 0}, {1, 0, 0}, nan, "max range nan is not a length (0: no limit)");
  refused({0, 0, 0}, {1, 0, 0}, 2e6, "max range 2e+06 m reaches beyond the map's key range (0: no limit)");
  // +inf is no limit, as 0.
  const RayCast inf = caster.cast({0.01, 0.02, 0.03}, {1, 0.1, 0}, std::numeric_limits<double>::infinity(),
                                  UnknownPolicy::kPass);
  const RayCast zero = caster.cast({0.01, 0.02, 0.03}, {1, 0.1, 0}, 0, UnknownPolicy::kPass);
  EXPECT_EQ(inf.cell, zero.cell);
  EXPECT_EQ(inf.stop, zero.stop);
  EXPECT_EQ(unknown_policy_from_string("pass"), UnknownPolicy::kPass);
  EXPECT_THROW(unknown_policy_from_string("ignore"), std::invalid_argument);
}

// An empty map: the start cell is unknown (stop), or nothing is ahead (pass).
// A direction's length by hypot: the squares of 1e308 overflowed to an infinite length, so the
// unit direction was zero and the walk never ended; those of 1e-200 underflowed to "zero".
TEST(RayCast, HugeAndTinyDirectionsAreTheirUnitDirection) {
  const BgkMap map = random_map(11, 0.1, false);
  const RayCaster caster(map);
  for (const Vec3d& unit : {Vec3d{1, 1, 0}, Vec3d{0.3, -0.2, 0.1}}) {
    const RayCast expected = caster.cast({0.05, 0.05, 0.05}, unit, 0, UnknownPolicy::kPass);
    for (double scale : {1e308, 1e-200}) {
      const RayCast cast =
          caster.cast({0.05, 0.05, 0.05}, {unit.x * scale, unit.y * scale, unit.z * scale}, 0, UnknownPolicy::kPass);
      EXPECT_EQ(cast.stop, expected.stop) << scale;
      EXPECT_EQ(cast.cell, expected.cell) << scale;
      EXPECT_NEAR(cast.distance, expected.distance, 1e-9) << scale;
    }
  }
}

TEST(RayCast, EmptyMap) {
  BuildParams params;
  const BgkMap map(params);
  const RayCast stop = cast_ray(map, {0.01, 0.02, 0.03}, {1, 0, 0}, 0, UnknownPolicy::kStop);
  EXPECT_EQ(stop.stop, RayStop::kUnknown);
  EXPECT_EQ(stop.distance, 0.0);
  EXPECT_EQ(stop.cell, (CellIndex{0, 0, 0}));
  const RayCast pass = cast_ray(map, {0.01, 0.02, 0.03}, {1, 0, 0}, 0, UnknownPolicy::kPass);
  EXPECT_EQ(pass.stop, RayStop::kMapEnd);
  EXPECT_EQ(pass.distance, 0.0);
  const RayCast ranged = cast_ray(map, {0.01, 0.02, 0.03}, {1, 0, 0}, 1.0, UnknownPolicy::kPass);
  EXPECT_EQ(ranged.stop, RayStop::kMaxRange);
  EXPECT_EQ(ranged.cell, (CellIndex{10, 0, 0}));
  EXPECT_EQ(ranged.distance, 1.0);
}

// A cell is reached when the ray enters it at t <= max_range: exactly at the range's end too, in
// either direction (0.125 m cells: the faces are exact).
TEST(RayCast, ReachesTheCellItEntersAtTheEndOfItsRange) {
  BuildParams params;
  params.grid.resolution_m = 0.125;
  params.grid.block_depth = 3;
  BgkMap map(params);
  const auto set = [&](const CellIndex& c, const Cell& value) {
    map.block_cells(map.ensure_slot(map.grid().block_of(c)))[map.grid().local_index(c)] = value;
  };
  set({0, 0, 0}, Cell{0.1f, 10.f});   // free
  set({1, 0, 0}, Cell{10.f, 0.1f});   // occupied
  set({-1, 0, 0}, Cell{10.f, 0.1f});  // occupied
  for (double sign : {1.0, -1.0}) {
    const RayCast at_end = cast_ray(map, {0.0625, 0.0625, 0.0625}, {sign, 0, 0}, 0.0625, UnknownPolicy::kStop);
    EXPECT_TRUE(at_end.hit()) << sign;
    EXPECT_EQ(at_end.cell, (CellIndex{sign > 0 ? 1 : -1, 0, 0}));
    EXPECT_EQ(at_end.distance, 0.0625);
    const RayCast short_of_it = cast_ray(map, {0.0625, 0.0625, 0.0625}, {sign, 0, 0}, 0.0624, UnknownPolicy::kStop);
    EXPECT_EQ(short_of_it.stop, RayStop::kMaxRange) << sign;
    EXPECT_EQ(short_of_it.cell, (CellIndex{0, 0, 0}));
    EXPECT_EQ(short_of_it.state, CellState::kFree);
    EXPECT_EQ(short_of_it.distance, 0.0624);
  }
}

// The shared DDA (the counting method's beams too): every cell a segment passes through, in
// order, and besides them only cells it touches at a tie.
TEST(CellWalk, SegmentVisitsEveryCellItPassesThroughInOrder) {
  for (double r : {0.125, 0.1}) {
    const Grid grid(GridParams{r, 3});
    const RaySet rays = test_rays(11, r);
    for (size_t i = 0; i < rays.origins.size(); ++i) {
      const Vec3d a = rays.origins[i];
      const double length = rays.ranges[i] == 0 ? 1.0 : rays.ranges[i];
      const Vec3d u = unit(rays.directions[i]);
      const Vec3d b{a.x + length * u.x, a.y + length * u.y, a.z + length * u.z};
      const std::vector<MetCell> met = cells_met(grid, a, u, length);
      std::vector<CellIndex> visited;
      for_each_cell_on_segment(grid, a, b, [&](const CellIndex& c) { visited.push_back(c); });
      const std::string what = describe(a, u, length, UnknownPolicy::kPass);
      double last_t = 0;
      for (const CellIndex& c : visited) {
        const MetCell* m = find_met(met, c);
        ASSERT_NE(m, nullptr) << what;
        EXPECT_GE(m->t_in, last_t - kTouch) << what;
        last_t = m->t_in;
      }
      for (const MetCell& m : met)
        if (m.passed && m.t_in < length - kTouch) {
          EXPECT_NE(std::find(visited.begin(), visited.end(), m.cell), visited.end()) << what;
        }
      EXPECT_EQ(visited.back(), grid.cell_of(b.x, b.y, b.z)) << what;
    }
  }
}

// ---- boxes and occupied cells --------------------------------------------------------------------

bool key_order(const BgkMap& map, const MapCell& a, const MapCell& b) {
  const BlockKey ka = map.grid().block_of(a.index), kb = map.grid().block_of(b.index);
  if (!(ka == kb)) return ka.z != kb.z ? ka.z < kb.z : (ka.y != kb.y ? ka.y < kb.y : ka.x < kb.x);
  return map.grid().local_index(a.index) < map.grid().local_index(b.index);
}

// Every cell of the region [-16, 16)^3 cell indices (all of random_map's blocks and more).
std::vector<MapCell> every_cell_of_region(const BgkMap& map) {
  std::vector<MapCell> cells;
  const int32_t z_lo = map.params().preprocess.planar ? map.params().planar_layer() : -16;
  const int32_t z_hi = map.params().preprocess.planar ? map.params().planar_layer() + 1 : 16;
  for (int32_t z = z_lo; z < z_hi; ++z)
    for (int32_t y = -16; y < 16; ++y)
      for (int32_t x = -16; x < 16; ++x) {
        MapCell c;
        c.index = {x, y, z};
        c.center = map.grid().cell_center_d(c.index);
        c.posterior = map.query(c.center.x, c.center.y, c.center.z);
        c.state = c.posterior.state(map.params().classify);
        cells.push_back(c);
      }
  return cells;
}

void expect_same_cells(const std::vector<MapCell>& got, std::vector<MapCell> expected, const BgkMap& map,
                       const std::string& what) {
  std::stable_sort(expected.begin(), expected.end(), [&](const MapCell& a, const MapCell& b) { return key_order(map, a, b); });
  ASSERT_EQ(got.size(), expected.size()) << what;
  for (size_t i = 0; i < got.size(); ++i) {
    ASSERT_EQ(got[i].index, expected[i].index) << what << " cell " << i;
    EXPECT_EQ(got[i].center.x, expected[i].center.x);
    EXPECT_EQ(got[i].center.y, expected[i].center.y);
    EXPECT_EQ(got[i].center.z, expected[i].center.z);
    EXPECT_EQ(got[i].posterior.alpha, expected[i].posterior.alpha);
    EXPECT_EQ(got[i].posterior.beta, expected[i].posterior.beta);
    EXPECT_EQ(got[i].state, expected[i].state);
  }
}

TEST(CellsInBox, EqualALoopOverEveryCell) {
  for (bool planar : {false, true}) {
    const double r = 0.1;
    const BgkMap map = random_map(planar ? 21 : 7, r, planar);
    const std::vector<MapCell> all = every_cell_of_region(map);
    std::mt19937 rng(9);
    std::uniform_real_distribution<double> coord(-1.55, 1.55);
    std::uniform_int_distribution<int> cell(-15, 14);
    size_t returned = 0;
    for (int i = 0; i < 60; ++i) {
      CellBox box{{coord(rng), coord(rng), coord(rng)}, {coord(rng), coord(rng), coord(rng)}};
      if (i % 4 == 0)  // bounds exactly on cell centres: those cells are inside
        box = {map.grid().cell_center_d({cell(rng), cell(rng), cell(rng)}),
               map.grid().cell_center_d({cell(rng), cell(rng), cell(rng)})};
      if (box.min.x > box.max.x) std::swap(box.min.x, box.max.x);
      if (box.min.y > box.max.y) std::swap(box.min.y, box.max.y);
      if (box.min.z > box.max.z) std::swap(box.min.z, box.max.z);
      if (i == 1) box.max = box.min;  // a point
      const double slack = 1e-9 * r;  // the documented tolerance of the bounds
      const auto in = [&](double c, double lo, double hi) { return c >= lo - slack && c <= hi + slack; };
      const auto inside = [&](const MapCell& c) {
        return in(c.center.x, box.min.x, box.max.x) && in(c.center.y, box.min.y, box.max.y) &&
               (planar || in(c.center.z, box.min.z, box.max.z));
      };
      std::vector<MapCell> evidence, every, occupied;
      for (const MapCell& c : all)
        if (inside(c)) {
          every.push_back(c);
          if (c.posterior.has_evidence) evidence.push_back(c);
          if (c.state == CellState::kOccupied) occupied.push_back(c);
        }
      const std::string what = std::string(planar ? "planar " : "") + "box " + std::to_string(i);
      expect_same_cells(cells_in_box(map, box), evidence, map, what + " with evidence");
      expect_same_cells(cells_in_box(map, box, true), every, map, what + " every cell");
      expect_same_cells(occupied_cells(map, &box), occupied, map, what + " occupied");
      EXPECT_EQ(cells_centred_in(map, box), static_cast<double>(every.size())) << what;
      returned += evidence.size();
    }
    EXPECT_GT(returned, 1000u);
    // The whole map's occupied cells.
    std::vector<MapCell> occupied;
    for (const MapCell& c : all)
      if (c.state == CellState::kOccupied) occupied.push_back(c);
    EXPECT_GT(occupied.size(), 40u);
    expect_same_cells(occupied_cells(map), occupied, map, "whole map");
  }
}

// A box of few blocks in a map of many takes its blocks by lookup, a large one by the map's
// slots: both give the same cells in the same order.
TEST(CellsInBox, LargeBoxesEqualTheWholeMap) {
  const BgkMap map = random_map(7, 0.1, false);
  const CellBox huge{{-1e6, -1e6, -1e6}, {1e6, 1e6, 1e6}};
  const std::vector<MapCell> whole = occupied_cells(map);
  const std::vector<MapCell> boxed = occupied_cells(map, &huge);
  ASSERT_EQ(whole.size(), boxed.size());
  for (size_t i = 0; i < whole.size(); ++i) EXPECT_EQ(whole[i].index, boxed[i].index);
  EXPECT_EQ(cells_in_box(map, huge).size(), map.cells_with_evidence());
}

TEST(CellsInBox, RefusesBadBoxes) {
  const BgkMap map = random_map(7, 0.1, false);
  const auto refused = [&](const CellBox& box, const std::string& message) {
    try {
      cells_in_box(map, box);
      ADD_FAILURE() << "not refused: " << message;
    } catch (const std::invalid_argument& e) {
      EXPECT_EQ(std::string(e.what()), message);
    }
  };
  refused({{0, 0, 1}, {1, 1, 0}}, "the box's minimum must not exceed its maximum on any axis");
  refused({{0, 0, std::nan("")}, {1, 1, 1}}, "the box's bounds must be finite");
  refused({{0, 0, 0}, {1, 1, 2e6}}, "the box lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
  EXPECT_THROW(for_each_cell_in_box(map, nullptr, CellSelection::kAll, [](const MapCell&) {}), std::invalid_argument);
}

// ---- a real map against liboctomap's castRay ----------------------------------------------------

// sim_structured at the la3dm settings, written as .bt (occupied and free by the map's thresholds,
// unknown cells left out) and read by liboctomap: castRay from every scan origin must end at the
// same cell. castRay measures its max range to cell centres, bgkmap to where the ray enters a cell:
// with a range, rays whose bgkmap hit lies near the range's end are not compared.
TEST(RayCast, SimStructuredAgreesWithOctomapCastRay) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  BuildParams params;
  params.grid.resolution_m = 0.1;
  params.preprocess.max_range_m = 8;
  params.preprocess.downsample_m = 0.1;
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  std::vector<Vec3d> origins;
  ScanSource source({datasets / "sim_structured"});
  for (Scan scan; source.next(scan);) {
    origins.push_back({scan.pose.position.x, scan.pose.position.y, scan.pose.position.z});
    mapper.insert(scan);
  }
  ASSERT_EQ(origins.size(), 12u);
  const BgkMap& map = mapper.map();
  const testing::TempDir dir("queries_octomap");
  write_map(dir / "m.bt", map);
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary((dir / "m.bt").string()));
  const RayCaster caster(map);
  std::mt19937 rng(17);
  std::normal_distribution<float> normal;
  constexpr double kRange = 12;
  size_t compared = 0, hits[2] = {0, 0}, skipped = 0, walked = 0;
  for (const Vec3d& origin : origins)
    for (int i = 0; i < 150; ++i) {
      const octomap::point3d o(float(origin.x), float(origin.y), float(origin.z)), d(normal(rng), normal(rng), 0.3f * normal(rng));
      const Vec3d ours_o{o.x(), o.y(), o.z()}, ours_d{d.x(), d.y(), d.z()};
      for (bool ignore_unknown : {false, true}) {
        octomap::point3d end;
        const bool octomap_hit = tree.castRay(o, d, end, ignore_unknown, ignore_unknown ? kRange : -1);
        const RayCast ours = caster.cast(ours_o, ours_d, ignore_unknown ? kRange : 0,
                                         ignore_unknown ? UnknownPolicy::kPass : UnknownPolicy::kStop);
        const std::string what = describe(ours_o, ours_d, 0, ignore_unknown ? UnknownPolicy::kPass : UnknownPolicy::kStop);
        const double dx = ours.center.x - ours_o.x, dy = ours.center.y - ours_o.y, dz = ours.center.z - ours_o.z;
        if (ignore_unknown && ours.hit() && std::sqrt(dx * dx + dy * dy + dz * dz) > kRange - 0.2) {
          ++skipped;
          continue;
        }
        ++compared;
        hits[ignore_unknown] += ours.hit();
        walked += !ignore_unknown && ours.distance > 0.5;
        ASSERT_EQ(ours.hit(), octomap_hit) << what;
        if (ours.hit() || !ignore_unknown) {  // the cell it stopped at: occupied, or the first unknown
          const octomap::OcTreeKey key = tree.coordToKey(end);
          EXPECT_EQ(int(key[0]) - 32768, ours.cell.x) << what;
          EXPECT_EQ(int(key[1]) - 32768, ours.cell.y) << what;
          EXPECT_EQ(int(key[2]) - 32768, ours.cell.z) << what;
        }
      }
    }
  std::printf("compared %zu casts with castRay (stopping at unknown cells: %zu hits, %zu stopped beyond 0.5 m; "
              "passing them: %zu hits), %zu skipped\n", compared, hits[0], walked, hits[1], skipped);
  EXPECT_GT(walked, 300u);
  EXPECT_GT(hits[1], 600u);
  EXPECT_LT(skipped, 20u);
}


// ---- the command line -----------------------------------------------------------------------------

using Result = testing::CommandResult;

Result cli(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

std::string printed(const char* format, ...) __attribute__((format(printf, 1, 2)));
std::string printed(const char* format, ...) {
  char line[512];
  va_list args;
  va_start(args, format);
  std::vsnprintf(line, sizeof line, format, args);
  va_end(args);
  return line;
}

std::string cell_line(const MapCell& c) {
  return printed("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %s\n", c.center.x, c.center.y, c.center.z, c.posterior.alpha,
                 c.posterior.beta, c.posterior.mean(), c.posterior.variance(), to_string(c.state));
}

// A scan of the walls of the room [-1.2, 1.2]^3 from near its centre.
Scan room_scan(int seed) {
  std::mt19937 rng(static_cast<uint32_t>(seed));
  std::uniform_real_distribution<float> on_wall(-1.2f, 1.2f), near_centre(-0.2f, 0.2f);
  std::uniform_int_distribution<int> wall(0, 5);
  Scan scan;
  scan.pose.position = {near_centre(rng), near_centre(rng), near_centre(rng)};
  for (int i = 0; i < 4000; ++i) {
    float p[3] = {on_wall(rng), on_wall(rng), on_wall(rng)};
    const int w = wall(rng);
    p[w / 2] = w % 2 ? 1.2f : -1.2f;
    scan.points.push_back({p[0], p[1], p[2]});
  }
  return scan;
}

class QueryCommand : public ::testing::Test {
 protected:
  void SetUp() override {
    std::filesystem::create_directories(dir_ / "scans");
    for (int i = 0; i < 3; ++i) write_pcd(dir_ / "scans" / ("s_" + std::to_string(i) + ".pcd"), room_scan(i));
    const Result r = cli("build -q " + path("scans") + " -o " + path("m.bgk") + " --backend cpu --threads 2");
    ASSERT_EQ(r.status, 0) << r.output;
    // Rays from inside the scanned box in random directions, some with a range.
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> coord(-1, 1), comp(-1, 1), range(0.2, 3);
    std::ofstream rays(dir_ / "rays.txt");
    rays << "# ox oy oz dx dy dz [max_range]\n\n";
    rays.precision(17);
    for (int i = 0; i < 200; ++i) {
      const Vec3d o{coord(rng), coord(rng), coord(rng)}, d{comp(rng), comp(rng), comp(rng)};
      const double max_range = i % 3 == 0 ? range(rng) : 0;
      rays << o.x << " " << o.y << " " << o.z << "\t" << d.x << " " << d.y << " " << d.z;
      if (i % 2 == 0) rays << " " << max_range;
      rays << "\n";
      rays_.add(o, d, i % 2 == 0 ? max_range : 0);
    }
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  // What `query --rays` must print: RayCaster on the map read back.
  std::string expected_rays(const BgkMap& map, UnknownPolicy policy) const {
    const RayCaster caster(map);
    std::string out;
    for (size_t i = 0; i < rays_.origins.size(); ++i) {
      const RayCast c = caster.cast(rays_.origins[i], rays_.directions[i], rays_.ranges[i], policy);
      out += printed("%d %.9g %.9g %.9g %.9g %s %s\n", c.hit() ? 1 : 0, c.center.x, c.center.y, c.center.z, c.distance,
                     to_string(c.state), to_string(c.stop));
    }
    return out;
  }

  testing::TempDir dir_{"query_command"};
  RaySet rays_;
};

TEST_F(QueryCommand, RaysBoxesAndOccupiedCellsPrintTheLibrarysAnswers) {
  const BgkMap map = read_native_map(dir_ / "m.bgk");
  for (UnknownPolicy policy : {UnknownPolicy::kStop, UnknownPolicy::kPass}) {
    const Result r = cli("query " + path("m.bgk") + " --rays " + path("rays.txt") + " --unknown " + to_string(policy));
    ASSERT_EQ(r.status, 0) << r.output;
    EXPECT_EQ(r.output, expected_rays(map, policy));
    size_t hits = 0;
    for (size_t at = 0; (at = r.output.find("\n1 ", at)) != std::string::npos; ++at) ++hits;
    if (policy == UnknownPolicy::kPass) {
      EXPECT_GT(hits, 50u);
    }
  }
  // Standard input, and stop as the default.
  Result r = testing::run_command("cat " + path("rays.txt") + " | " + BGKMAP_CLI + " query " + path("m.bgk") + " --rays -");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, expected_rays(map, UnknownPolicy::kStop));

  const CellBox box{{0.6, -0.4, -0.3}, {1.3, 0.7, 0.35}};
  std::string every, evidence, occupied, all_occupied;
  for (const MapCell& c : cells_in_box(map, box, true)) every += cell_line(c);
  for (const MapCell& c : cells_in_box(map, box)) evidence += cell_line(c);
  for (const MapCell& c : occupied_cells(map, &box)) occupied += cell_line(c);
  for (const MapCell& c : occupied_cells(map)) all_occupied += cell_line(c);
  ASSERT_GT(std::count(occupied.begin(), occupied.end(), '\n'), 10);
  const std::string q = "query " + path("m.bgk");
  r = cli(q + " --box 0.6,-0.4,-0.3,1.3,0.7,0.35");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, evidence);
  r = cli(q + " --box 0.6,-0.4,-0.3,1.3,0.7,0.35 --include-unobserved");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, every);
  EXPECT_EQ(std::count(every.begin(), every.end(), '\n'), 7 * 11 * 7);  // centres 0.65..1.25, -0.35..0.65, -0.25..0.35 (0.35: the bound)
  r = cli(q + " --box 0.6,-0.4,-0.3,1.3,0.7,0.35 --occupied");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, occupied);
  r = cli(q + " --occupied");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(r.output, all_occupied);
}

// The map's blocks split between two ranks' shards by a spatial partition, in a shard folder.
void write_two_shards(const BgkMap& map, const std::filesystem::path& shards) {
  TileCosts costs;
  for (uint32_t s = 0; s < map.block_count(); ++s) costs.add(tile_code(map.key_of_slot(s)), 1.0);
  const SpatialPartition partition(2, costs.sorted());
  std::filesystem::create_directories(shards);
  ShardManifest manifest;
  manifest.ranks = 2;
  manifest.scans = 3;
  manifest.partition = partition.first_codes();
  for (int rank = 0; rank < 2; ++rank) {
    BgkMap part(map.params());
    for (uint32_t s = 0; s < map.block_count(); ++s) {
      if (partition.owner(map.key_of_slot(s)) != rank) continue;
      const uint32_t slot = part.ensure_slot(map.key_of_slot(s));
      std::copy(map.block_cells(s), map.block_cells(s) + map.cells_per_block(), part.block_cells(slot));
    }
    ASSERT_GT(part.block_count(), 0u) << rank;
    write_shard(shards, rank, part, std::vector<uint32_t>(part.block_count(), 0));
    manifest.shard_maps.push_back(shard_map_name(rank));
    manifest.shard_orders.push_back(shard_order_name(rank));
  }
  write_manifest(shards / kShardManifestName, manifest);
}

// A shard folder answers as the map its shards merge to.
TEST_F(QueryCommand, AShardFolderAnswersAsTheMergedMap) {
  const BgkMap map = read_native_map(dir_ / "m.bgk");
  const std::filesystem::path shards = dir_ / "shards";
  write_two_shards(map, shards);
  for (const std::string& args : {std::string(" --rays ") + path("rays.txt") + " --unknown pass", std::string(" --occupied"),
                                  std::string(" --box -1,-1,-1,1,1,1")}) {
    const Result single = cli("query " + path("m.bgk") + args), sharded = cli("query " + shards.string() + args);
    ASSERT_EQ(single.status, 0) << single.output;
    ASSERT_EQ(sharded.status, 0) << sharded.output;
    EXPECT_GT(single.output.size(), 1000u);
    EXPECT_EQ(single.output, sharded.output) << args;
  }
}

// A planar map's shards answer a point at any height from the shard holding its layer cell (the
// block of the point's own height may belong to another rank).
TEST_F(QueryCommand, APlanarShardFolderAnswersPointsAtAnyHeight) {
  ASSERT_EQ(cli("build -q " + path("scans") + " -o " + path("planar.bgk") + " --2d --backend cpu --threads 2").status, 0);
  const std::filesystem::path shards = dir_ / "planar_shards";
  write_two_shards(read_native_map(dir_ / "planar.bgk"), shards);
  std::ofstream points(dir_ / "points.txt");
  const double heights[] = {0.05, -40, -3.3, 4.1, 7.7, 60};
  for (int i = 0; i < 600; ++i)
    points << -1.15 + 0.0038 * i << " " << 1.1 - 0.0036 * i << " " << heights[i % 6] << "\n";
  points.close();
  const Result single = cli("query " + path("planar.bgk") + " --points " + path("points.txt"));
  const Result sharded = cli("query " + shards.string() + " --points " + path("points.txt"));
  ASSERT_EQ(single.status, 0) << single.output;
  ASSERT_EQ(sharded.status, 0) << sharded.output;
  size_t observed = 0;
  for (size_t at = 0; (at = single.output.find(" free\n", at)) != std::string::npos; ++at) ++observed;
  EXPECT_GT(observed, 100u);
  std::istringstream a(single.output), b(sharded.output);
  size_t lines = 0, differing = 0;
  for (std::string la, lb; std::getline(a, la) && std::getline(b, lb); ++lines) differing += la != lb;
  EXPECT_EQ(lines, 600u);
  EXPECT_EQ(differing, 0u) << "of 600 points";
}

// Bad lines name the file and the line, quoting at most 80 bytes; folders and missing files,
// flags without their mode and bad boxes are one-line errors.
TEST_F(QueryCommand, BadInputIsAOneLineError) {
  const auto error = [&](const std::string& args, const std::string& message) {
    const Result r = cli("query " + path("m.bgk") + " " + args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << ": " << r.output;
    EXPECT_LE(std::count(r.output.begin(), r.output.end(), '\n'), 2) << r.output;  // CLI11 adds a --help hint
  };
  const auto rays_file = [&](const std::string& name, const std::string& text) {
    testing::write_bytes(dir_ / name, text);
    return path(name);
  };
  error("--rays " + rays_file("few.txt", "0 0 0 1 0 0\n# c\n0 0 0 1 0\n"),
        path("few.txt") + ": line 3: expected 'ox oy oz dx dy dz [max_range]', got '0 0 0 1 0'");
  error("--rays " + rays_file("many.txt", "0 0 0 1 0 0 1 2\n"), path("many.txt") + ": line 1: expected 'ox oy oz dx");
  error("--rays " + rays_file("word.txt", "0 0 0 1 0 x\n"), path("word.txt") + ": line 1: expected");
  const std::string long_line = "1 2 3 " + std::string(200, 'z');
  error("--rays " + rays_file("long.txt", long_line + "\n"),
        "line 1: expected 'ox oy oz dx dy dz [max_range]', got '" + long_line.substr(0, 80) + "...'");
  error("--rays " + rays_file("zero.txt", "0 0 0 1 0 0\n0 0 0 0 0 0 5\n"),
        path("zero.txt") + ": line 2: the ray's direction is zero ('0 0 0 0 0 0 5')");
  error("--rays " + rays_file("neg.txt", "0 0 0 1 0 0 -2\n"), path("neg.txt") + ": line 1: max range -2 is not a length");
  error("--rays " + rays_file("far.txt", "3e6 0 0 1 0 0\n"), "line 1: the ray's origin lies beyond the map's key range");
  error("--rays " + rays_file("nan.txt", "nan 0 0 1 0 0\n"), "line 1: the ray's origin is not finite");
  error("--rays " + path("scans"), path("scans") + ": is a folder, not a file of rays");
  error("--rays " + path("missing.txt"), path("missing.txt") + ": cannot open");
  error("--points " + path("scans"), path("scans") + ": is a folder, not a points file");
  error("--unknown pass", "--unknown requires --rays");
  error("--rays " + path("rays.txt") + " --unknown ignore", "--unknown: ignore not in {stop,pass}");
  error("--rays " + path("rays.txt") + " --box 0,0,0,1,1,1", "--rays excludes --box");
  error("--include-unobserved", "--include-unobserved requires --box");
  error("--box 0,0,0,1,1,1 --occupied --include-unobserved", "excludes --include-unobserved");
  error("--box 0,0,0,1,1", "--box");
  error("--box 0,0,0,1,1,x", "--box");
  error("--box 1,0,0,0,1,1", "bgkmap: error: --box: the box's minimum must not exceed its maximum on any axis");
  error("--box 0,0,0,1,1,2e6", "bgkmap: error: --box: the box lies beyond the map's key range");
}

}  // namespace
}  // namespace bgkmap
