// The `campus` preset: ~600 x 350 m of flat ground crossed by a grid of roads, five blocks of
// buildings (boxes, some turned or L-shaped, a few round towers), a park, street trees, lamp posts
// and parked cars; a car-mounted VLP-16 drives a 2 km loop through it. Thousands of primitives:
// the benchmark for large maps.
#include <cmath>
#include <vector>

#include "bgkmap/sim/presets.hpp"
#include "preset_random.hpp"

namespace bgkmap::sim {

namespace {
const std::vector<double> kRoadsX{20, 200, 400, 580};  // roads running along y, at these x
const std::vector<double> kRoadsY{20, 175, 330};       // roads running along x, at these y
constexpr double kRoadHalfWidth = 6;
constexpr double kSensorHeight = 1.8;

bool near_crossing(double along, const std::vector<double>& crossings, double margin) {
  for (double c : crossings)
    if (std::abs(along - c) < margin) return true;
  return false;
}

void add_tree(std::vector<Primitive>& p, PresetRandom& rng, double x, double y) {
  const double trunk_height = rng.uniform(2.5, 4.0), canopy = rng.uniform(1.8, 3.0);
  p.push_back(Cylinder({x, y, -0.2}, {x, y, trunk_height}, rng.uniform(0.15, 0.3)));
  p.push_back(Sphere({x, y, trunk_height + 0.6 * canopy}, canopy));
}

void add_car(std::vector<Primitive>& p, PresetRandom& rng, double x, double y, double yaw_deg) {
  const double c = std::cos(yaw_deg * M_PI / 180), s = std::sin(yaw_deg * M_PI / 180);
  const double cabin_shift = rng.uniform(-0.4, 0.2);
  p.push_back(Box({x, y, 0.8}, {4.4, 1.8, 1.0}, {0, 0, yaw_deg}));
  p.push_back(Box({x + c * cabin_shift, y + s * cabin_shift, 1.55}, {2.2, 1.6, 0.5}, {0, 0, yaw_deg}));
}

// Street furniture along one road: trees (9.5 m out, every 10 m), lamp posts (7 m, every 30 m)
// and parked cars (4.2 m)
// on both sides, kept clear of the crossings.
void furnish_road(std::vector<Primitive>& p, PresetRandom& rng, bool along_x, double at, double from, double to,
                  const std::vector<double>& crossings) {
  for (int side : {-1, 1}) {
    for (double d = from; d <= to; d += 10) {
      if (near_crossing(d, crossings, 16) || rng.chance(0.15)) continue;
      const double off = at + side * 9.5;
      along_x ? add_tree(p, rng, d, off) : add_tree(p, rng, off, d);
    }
    for (double d = from + 6; d <= to; d += 30) {
      if (near_crossing(d, crossings, 14)) continue;
      const double off = at + side * 7.0;
      const Vec3d base = along_x ? Vec3d{d, off, 0} : Vec3d{off, d, 0};
      p.push_back(Cylinder({base.x, base.y, -0.2}, {base.x, base.y, 6.0}, 0.1));
    }
    for (double d = from + 3; d <= to; d += 7) {
      if (near_crossing(d, crossings, 18) || !rng.chance(0.35)) continue;
      const double off = at + side * 4.2;
      along_x ? add_car(p, rng, d, off, 0) : add_car(p, rng, off, d, 90);
    }
  }
}

// Buildings on a grid of lots inside a block, set back from the roads.
void build_block(std::vector<Primitive>& p, PresetRandom& rng, double x0, double y0, double x1, double y1) {
  const double setback = 12;
  x0 += setback, y0 += setback, x1 -= setback, y1 -= setback;
  const int nx = rng.integer(2, 3), ny = 2;
  const double lot_x = (x1 - x0) / nx, lot_y = (y1 - y0) / ny;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j) {
      if (rng.chance(0.12)) continue;  // an empty lot
      const double cx = x0 + (i + 0.5) * lot_x, cy = y0 + (j + 0.5) * lot_y;
      const double height = rng.uniform(6, 25);
      if (rng.chance(0.1)) {  // a round tower
        const double r = 0.35 * std::fmin(lot_x, lot_y);
        p.push_back(Cylinder({cx, cy, -0.5}, {cx, cy, height + 8}, r));
        continue;
      }
      const double sx = rng.uniform(0.5, 0.8) * lot_x, sy = rng.uniform(0.5, 0.8) * lot_y;
      const double yaw = rng.chance(0.3) ? rng.uniform(-15, 15) : 0.0;
      p.push_back(Box({cx, cy, height / 2}, {sx, sy, height}, {0, 0, yaw}));
      // An L-shaped wing: a lower box on the +y side of one half, staying inside the lot.
      const double wing_out = std::fmin(0.5 * sy, 0.5 * lot_y - 0.5 * sy - 2);
      if (rng.chance(0.35) && wing_out >= 4) {
        const double wing_h = rng.uniform(4, height);
        const double c = std::cos(yaw * M_PI / 180), s = std::sin(yaw * M_PI / 180);
        const double ox = -0.25 * sx, oy = 0.5 * sy + 0.5 * wing_out - 0.5;  // in the building's frame
        p.push_back(Box({cx + c * ox - s * oy, cy + s * ox + c * oy, wing_h / 2}, {0.5 * sx, wing_out + 1, wing_h},
                        {0, 0, yaw}));
      }
    }
}

void plant_park(std::vector<Primitive>& p, PresetRandom& rng, double x0, double y0, double x1, double y1) {
  std::vector<std::pair<double, double>> trees;
  for (int tries = 0; trees.size() < 260 && tries < 20000; ++tries) {
    const double x = rng.uniform(x0 + 12, x1 - 12), y = rng.uniform(y0 + 12, y1 - 12);
    bool crowded = false;
    for (const auto& t : trees) crowded = crowded || std::hypot(t.first - x, t.second - y) < 5.5;
    if (crowded) continue;
    trees.push_back({x, y});
    add_tree(p, rng, x, y);
  }
  for (int k = 0; k < 80; ++k)  // bushes
    p.push_back(Sphere({rng.uniform(x0 + 10, x1 - 10), rng.uniform(y0 + 10, y1 - 10), 0.2}, rng.uniform(0.6, 1.2)));
}
}  // namespace

SimulationSpec make_campus_preset() {
  SimulationSpec spec;
  spec.name = "campus";
  spec.truth_resolution_m = 0.2;
  spec.sensor = sensor_preset("vlp16");
  // Bounds on multiples of 6.4 m (z: 3.2 m) keep the truth octree's cubes large along the edges.
  spec.scene.bounds = Box3d{{-6.4, -6.4, -3.2}, {608, 358.4, 38.4}};
  auto& p = spec.scene.primitives;
  p.push_back(HalfSpace({0, 0, 0}, {0, 0, 1}));  // ground

  PresetRandom rng(1897);
  for (size_t bx = 0; bx + 1 < kRoadsX.size(); ++bx)
    for (size_t by = 0; by + 1 < kRoadsY.size(); ++by) {
      const double x0 = kRoadsX[bx] + kRoadHalfWidth, x1 = kRoadsX[bx + 1] - kRoadHalfWidth;
      const double y0 = kRoadsY[by] + kRoadHalfWidth, y1 = kRoadsY[by + 1] - kRoadHalfWidth;
      if (bx == 1 && by == 1) plant_park(p, rng, x0, y0, x1, y1);
      else build_block(p, rng, x0, y0, x1, y1);
    }
  for (double y : kRoadsY) furnish_road(p, rng, true, y, kRoadsX.front(), kRoadsX.back(), kRoadsX);
  for (double x : kRoadsX) furnish_road(p, rng, false, x, kRoadsY.front(), kRoadsY.back(), kRoadsY);

  // Down the middle of the roads, round the outside and through the middle blocks.
  spec.trajectory.scans = 3000;
  spec.trajectory.closed = true;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {20, 20}, {580, 20}, {580, 330}, {400, 330}, {400, 175}, {200, 175}, {200, 330}, {20, 330}})
    spec.trajectory.waypoints.push_back({{x, y, kSensorHeight}, std::nullopt});
  return spec;
}

}  // namespace bgkmap::sim
