#include "bgkmap/eval/dynamic_cells.hpp"

#include <cmath>

#include "bgkmap/sim/raycaster.hpp"
#include "bgkmap/sim/scanner.hpp"

namespace bgkmap::eval {

namespace {

// Calls visit(cell) for each cell whose centre lies inside `shape` and in no static solid.
template <typename Visit>
void for_each_covered_cell(const sim::Primitive& shape, const sim::Scene& scene, const Grid& grid, Visit&& visit) {
  for_each_cell_in(grid, sim::bounds(shape)->padded(), [&](const CellIndex& c) {
    const Vec3d p = grid.cell_center_d(c);
    if (sim::contains(shape, p) && !scene.contains(p)) visit(c);
  });
}

class StaticCellsTruth : public Truth {
 public:
  StaticCellsTruth(const Truth& truth, const DynamicCells& dynamic) : truth_(truth), dynamic_(dynamic) {}
  sim::Box3d region() const override { return truth_.region(); }
  TruthLabel label(const CellIndex& c) const override {
    return dynamic_.is_dynamic(c) ? TruthLabel::kUnknown : truth_.label(c);
  }

 private:
  const Truth& truth_;
  const DynamicCells& dynamic_;
};

}  // namespace

uint64_t DynamicCells::key(const CellIndex& c) {
  // Cell indices of a truth region fit 21 bits a side (the truth octree's reach is 16).
  const auto part = [](int32_t v) { return static_cast<uint64_t>(static_cast<uint32_t>(v) & 0x1FFFFFu); };
  return part(c.x) | (part(c.y) << 21) | (part(c.z) << 42);
}

DynamicCells::DynamicCells(const sim::SimulationSpec& spec, const Grid& grid)
    : spec_(spec), grid_(grid), poses_(sim::sample_poses(spec.trajectory)),
      directions_(sim::beam_directions(spec.sensor)), bounds_(sim::Box3d::empty()) {
  for (const sim::DynamicObject& object : spec.scene.dynamic)
    for (int s = 0; s < spec.trajectory.scans; ++s) {
      if (!object.present_at(s)) continue;
      for_each_covered_cell(object.shape_at(s), spec.scene, grid_, [&](const CellIndex& c) {
        cells_.try_emplace(key(c), Track{c});
        const Vec3d p = grid_.cell_center_d(c);
        bounds_.expand(p);
      });
      if (!object.moves()) break;  // the same cells at every scan
    }
  const double half = 0.5 * grid_.resolution();
  bounds_ = {{bounds_.min.x - half, bounds_.min.y - half, bounds_.min.z - half},
             {bounds_.max.x + half, bounds_.max.y + half, bounds_.max.z + half}};
}

void DynamicCells::advance() {
  const int scan = next_scan_++;
  for (auto& [k, track] : cells_) track.covered_now = false;
  for (const sim::DynamicObject& object : spec_.scene.dynamic) {
    if (!object.present_at(scan)) continue;
    for_each_covered_cell(object.shape_at(scan), spec_.scene, grid_, [&](const CellIndex& c) {
      Track& track = cells_.at(key(c));
      track.last_covered = scan;
      track.seen_through = -1;
      track.covered_now = true;
      track.by_walker = object.moves();
    });
  }
  if (scan < static_cast<int>(poses_.size()) && !cells_.empty()) mark_seen_through(scan, sim::scene_at(spec_.scene, scan));
}

// Every beam of the scan, cast into the scene as it is then, samples its free stretch inside the
// dynamic cells' box every quarter cell.
void DynamicCells::mark_seen_through(int scan, const sim::Scene& now) {
  const sim::Raycaster raycaster(now);
  const Pose& pose = poses_[scan];
  const sim::Mat3 rotation = sim::rotation_of(pose);
  const Vec3d origin{pose.position.x, pose.position.y, pose.position.z};
  const double step = 0.25 * grid_.resolution(), max_range = spec_.sensor.max_range_m;
  for (const Vec3d& d : directions_) {
    const sim::Ray ray{origin, rotation * d};
    double t0, t1;
    if (!sim::clip_ray_to_box(ray, bounds_, t0, t1)) continue;
    const auto hit = raycaster.cast(ray, max_range);
    const double end = std::fmin(t1, hit ? hit->t : max_range);
    for (double t = std::fmax(t0, 0.0); t < end; t += step) {
      const Vec3d p = ray.at(t);
      const auto it = cells_.find(key(grid_.cell_of(p.x, p.y, p.z)));
      if (it == cells_.end()) continue;
      Track& track = it->second;
      if (!track.covered_now && track.last_covered >= 0 && track.seen_through < 0) track.seen_through = scan;
    }
  }
}

DynamicScores DynamicCells::score(const MapSampler& sample, double free_threshold, double occupied_threshold) const {
  DynamicScores out;
  const int now = next_scan_ - 1;
  for (const auto& [k, track] : cells_) {
    if (track.covered_now || track.seen_through < 0) continue;
    VacatedScores& v = track.by_walker ? out.trail : out.removed;
    const double p = sample(grid_.cell_center_d(track.index)).score;
    const bool free = p < free_threshold;
    ++v.cells;
    v.read_free += free;
    v.read_occupied += p > occupied_threshold;
    if (now - track.seen_through >= kSettleScans) {
      ++v.settled_cells;
      v.settled_free += free;
    }
  }
  return out;
}

std::unique_ptr<Truth> static_cells_truth(const Truth& truth, const DynamicCells& dynamic) {
  return std::make_unique<StaticCellsTruth>(truth, dynamic);
}

}  // namespace bgkmap::eval
