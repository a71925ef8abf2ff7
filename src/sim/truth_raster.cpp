#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/sim/truth.hpp"

namespace bgkmap::sim {

namespace {

enum class State { kFree, kOccupied, kMixed };

// Depth-first split of the octree over the region. Each cube carries the primitives that may
// still change within it (those whose relation to it was kMixed); cubes know their state as soon
// as one primitive contains them all or none is left. Cubes come out maximal: no eight emitted
// siblings share a state.
class Rasterizer {
 public:
  Rasterizer(const Scene& scene, CellIndex lo, CellIndex hi, double resolution,
             const std::function<void(const TruthCube&)>& emit)
      : scene_(scene), lo_(lo), hi_(hi), resolution_(resolution), emit_(emit), candidates_(kTruthLevels + 1) {}

  TruthStats run() {
    std::vector<uint32_t> all(scene_.primitives.size());
    for (uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    const int32_t half = 1 << (kTruthLevels - 1);
    const CellIndex root{-half, -half, -half};
    const Outcome outcome = visit(root, kTruthLevels, State::kMixed, all);
    if (outcome == Outcome::kFree || outcome == Outcome::kOccupied) emit(root, kTruthLevels, outcome == Outcome::kOccupied);
    return stats_;
  }

 private:
  bool disjoint_from_region(const CellIndex& min, int32_t size) const {
    return min.x > hi_.x || min.y > hi_.y || min.z > hi_.z || min.x + size - 1 < lo_.x || min.y + size - 1 < lo_.y ||
           min.z + size - 1 < lo_.z;
  }
  bool within_region(const CellIndex& min, int32_t size) const {
    return min.x >= lo_.x && min.y >= lo_.y && min.z >= lo_.z && min.x + size - 1 <= hi_.x &&
           min.y + size - 1 <= hi_.y && min.z + size - 1 <= hi_.z;
  }
  Vec3d centre(int32_t cx, int32_t cy, int32_t cz) const {
    return {(cx + 0.5) * resolution_, (cy + 0.5) * resolution_, (cz + 0.5) * resolution_};
  }

  void emit(const CellIndex& min, int level, bool occupied) {
    const uint64_t cells = uint64_t{1} << (3 * level);
    (occupied ? stats_.occupied_cells : stats_.free_cells) += cells;
    ++stats_.cubes;
    emit_(TruthCube{min, level, occupied});
  }

  // What a visited cube left for its parent to do.
  enum class Outcome {
    kNothing,   // no cell in the region
    kFree,      // uniform and wholly in the region, not emitted yet: the parent may merge it
    kOccupied,  // likewise
    kEmitted,   // its cells went out as smaller cubes
  };

  Outcome uniform(bool occupied) const { return occupied ? Outcome::kOccupied : Outcome::kFree; }

  Outcome visit(const CellIndex& min, int level, State state, const std::vector<uint32_t>& parent_candidates) {
    const int32_t size = int32_t{1} << level;
    if (disjoint_from_region(min, size)) return Outcome::kNothing;
    std::vector<uint32_t>& mine = candidates_[level];
    mine.clear();
    if (state == State::kMixed) {
      // The box spanned by the cube's cell centres: what the relation must hold for.
      const Box3d box{centre(min.x, min.y, min.z), centre(min.x + size - 1, min.y + size - 1, min.z + size - 1)};
      state = State::kFree;
      for (uint32_t i : parent_candidates) {
        const BoxRelation r = relation(scene_.primitives[i], box);
        if (r == BoxRelation::kInside) {
          state = State::kOccupied;
          break;
        }
        if (r == BoxRelation::kMixed) {
          mine.push_back(i);
          state = State::kMixed;
        }
      }
    }
    if (level == 0) {
      bool occupied = state == State::kOccupied;
      if (state == State::kMixed) {
        const Vec3d c = centre(min.x, min.y, min.z);
        for (uint32_t i : mine)
          if ((occupied = contains(scene_.primitives[i], c))) break;
      }
      return uniform(occupied);
    }
    if (state != State::kMixed && within_region(min, size)) return uniform(state == State::kOccupied);

    // Split. Eight uniform children of one state make a uniform cube (what OctoMap's prune would
    // merge); otherwise the uniform children are emitted here.
    const int32_t h = size / 2;
    CellIndex child_min[8];
    Outcome outcome[8];
    for (int child = 0; child < 8; ++child) {  // octree child order: x is bit 0, y bit 1, z bit 2
      child_min[child] = {min.x + ((child & 1) ? h : 0), min.y + ((child & 2) ? h : 0), min.z + ((child & 4) ? h : 0)};
      outcome[child] = visit(child_min[child], level - 1, state, mine);
    }
    bool all_same = outcome[0] == Outcome::kFree || outcome[0] == Outcome::kOccupied;
    for (int child = 1; child < 8 && all_same; ++child) all_same = outcome[child] == outcome[0];
    if (all_same) return outcome[0];
    for (int child = 0; child < 8; ++child)
      if (outcome[child] == Outcome::kFree || outcome[child] == Outcome::kOccupied)
        emit(child_min[child], level - 1, outcome[child] == Outcome::kOccupied);
    return Outcome::kEmitted;
  }

  const Scene& scene_;
  CellIndex lo_, hi_;  // inclusive range of cells whose centre is in the region
  double resolution_;
  const std::function<void(const TruthCube&)>& emit_;
  std::vector<std::vector<uint32_t>> candidates_;  // one list per level, reused by siblings
  TruthStats stats_;
};

}  // namespace

namespace {
struct CellRange {
  CellIndex lo, hi;  // inclusive
  bool empty;
};

// Cells whose centre (c + 0.5) * resolution lies in the region.
CellRange cells_of_region(const Box3d& region, double resolution) {
  if (!(resolution > 0) || !std::isfinite(resolution)) throw std::invalid_argument("truth resolution must be positive");
  auto first = [&](double v) { return std::ceil(v / resolution - 0.5); };
  auto last = [&](double v) { return std::floor(v / resolution - 0.5); };
  const double limit = 1 << (kTruthLevels - 1);
  const double lx = first(region.min.x), ly = first(region.min.y), lz = first(region.min.z);
  const double hx = last(region.max.x), hy = last(region.max.y), hz = last(region.max.z);
  if (!(lx >= -limit && ly >= -limit && lz >= -limit && hx < limit && hy < limit && hz < limit))
    throw std::invalid_argument("the truth region does not fit OctoMap's 2^16 cells per axis at resolution " +
                                std::to_string(resolution) + " m: use a coarser truth resolution");
  return {{static_cast<int32_t>(lx), static_cast<int32_t>(ly), static_cast<int32_t>(lz)},
          {static_cast<int32_t>(hx), static_cast<int32_t>(hy), static_cast<int32_t>(hz)},
          lx > hx || ly > hy || lz > hz};
}
}  // namespace

void check_truth_region(const Box3d& region, double resolution) { cells_of_region(region, resolution); }

TruthStats rasterize_truth(const Scene& scene, const Box3d& region, double resolution,
                           const std::function<void(const TruthCube&)>& emit) {
  const CellRange cells = cells_of_region(region, resolution);
  if (cells.empty) return {};
  return Rasterizer(scene, cells.lo, cells.hi, resolution, emit).run();
}

}  // namespace bgkmap::sim
