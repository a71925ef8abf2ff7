// --method octomap: OcTree::insertPointCloud per scan (origin = the scan's sensor position, max
// range = --max-range, resolution = --resolution), so its probabilities are OctoMap's own. It
// writes .ot / .bt of that tree; it has no BGK posterior, so .bgk is refused.
#include <octomap/OcTree.h>
#include <omp.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "io/octomap_tree_write.hpp"
#include "io/probability_tree.hpp"
#include "methods/octomap/octomap_method.hpp"
#include "core/number_text.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

class OctomapMethod final : public MappingMethod {
 public:
  OctomapMethod(const BuildParams& params, const OctomapParams& method_params)
      : params_(params), tree_(params.grid.resolution_m) {
    tree_.setProbHit(method_params.prob_hit);
    tree_.setProbMiss(method_params.prob_miss);
    tree_.setClampingThresMin(method_params.clamp_min);
    tree_.setClampingThresMax(method_params.clamp_max);
  }

  std::string name() const override { return "octomap"; }

  void check_output(const std::filesystem::path& file) const override {
    require_tree_output(file, "octomap");
  }

  void insert_prepared(PreparedScan&& prepared) override {
    const Clock::time_point start = Clock::now();
    PreprocessCounts& counts = counts_.preprocess;
    counts += prepared.counts;
    const std::vector<Vec3f>& points = prepared.points;
    const double preprocess_s = prepared.seconds;

    const Clock::time_point t = Clock::now();
    const Vec3f& o = prepared.origin;
    const double max_range = params_.preprocess.max_range_m;
    octomap::Pointcloud cloud;
    cloud.reserve(points.size());
    for (const Vec3f& p : points) {
      const double range = std::sqrt(double(p.x - o.x) * (p.x - o.x) + double(p.y - o.y) * (p.y - o.y) +
                                     double(p.z - o.z) * (p.z - o.z));
      const ReturnKind kind = classify_return(range, params_.preprocess);
      if (kind != ReturnKind::kHit) {
        ++counts.beyond_max_range;
        if (kind == ReturnKind::kBeyondDropped) continue;
      } else {
        ++counts.hits;
      }
      cloud.push_back(p.x, p.y, p.z);
    }
    counts.beams += cloud.size();
    for (size_t i = 0; i < cloud.size(); ++i) require_traceable_ray(octomap::point3d(o.x, o.y, o.z), cloud[i], max_range);
    require_ray_memory(cloud, o, max_range);
    if (cloud.size() > 0) {
      // OctoMap's computeUpdate (header code, compiled here with OpenMP) calls
      // omp_set_num_threads(1), which would leave every later OpenMP region of this thread
      // (the CPU back end of another method in the same process) on one thread.
      const int omp_threads = omp_get_max_threads();
      tree_.insertPointCloud(cloud, octomap::point3d(o.x, o.y, o.z), max_range > 0 ? max_range : -1.0);
      omp_set_num_threads(omp_threads);
    }
    const double compute_s = seconds_since(t);

    ++counts_.scans;
    timing_.add_scan(preprocess_s, 0.0, 0.0, compute_s, prepared.seconds + seconds_since(start));
  }

  // liboctomap traces a ray into a fixed buffer of KeyRay::maxSize keys without bounds checks, and
  // divides by its float length: rays it would overflow, loop on or drop (beyond its key range,
  // with a warning per ray) are refused here, naming the flags that make them fit.
  void require_traceable_ray(const octomap::point3d& origin, const octomap::point3d& point, double max_range) const {
    octomap::point3d end = point;
    if (max_range > 0 && (point - origin).norm() > max_range)  // as computeUpdate shortens it
      end = origin + (point - origin).normalized() * static_cast<float>(max_range);
    const auto where = [&] {
      char text[200];
      std::snprintf(text, sizeof text, "scan %llu: the ray from (%.6g, %.6g, %.6g) to (%.6g, %.6g, %.6g)",
                    static_cast<unsigned long long>(counts_.scans + 1), origin.x(), origin.y(), origin.z(), point.x(),
                    point.y(), point.z());
      return std::string(text);
    };
    octomap::OcTreeKey from, to;
    if (!tree_.coordToKeyChecked(origin, from) || !tree_.coordToKeyChecked(end, to))
      throw std::runtime_error("--method octomap: " + where() + " leaves liboctomap's key range (+-" +
                                               number_text(32768 * tree_.getResolution()) +
                                               " m at this --resolution): give a coarser --resolution or a --max-range");
    if (from == to) return;  // one cell: liboctomap traces nothing
    const float length = (end - origin).norm();
    if (!(length > 0) || !std::isfinite(length))
      throw std::runtime_error("--method octomap: " + where() + " is too short for liboctomap to trace (its float length is " +
                                               number_text(length) + " m across a cell boundary)");
    static const size_t capacity = octomap::KeyRay().sizeMax();
    uint64_t steps = 0;
    for (int axis = 0; axis < 3; ++axis) steps += static_cast<uint64_t>(std::abs(int(to[axis]) - int(from[axis])));
    if (steps + 2 >= capacity)
      throw std::runtime_error("--method octomap: " + where() + " crosses " + std::to_string(steps + 1) +
                                               " cells, more than liboctomap's ray buffer of " +
                                               std::to_string(capacity) +
                                               ": give a shorter --max-range or a coarser --resolution");
  }

  // insertPointCloud gathers the keys of every cell on the scan's rays in a hash set, then adds
  // the new ones as leaves: refused before it starts when one entry and one leaf (about 80 bytes)
  // per cell crossed would take the process beyond the memory limit.
  void require_ray_memory(const octomap::Pointcloud& cloud, const Vec3f& o, double max_range) const {
    constexpr double kBytesPerRayCell = 80;
    double cells = 0;
    for (size_t i = 0; i < cloud.size(); ++i) {
      double length = (cloud[i] - octomap::point3d(o.x, o.y, o.z)).norm();
      if (max_range > 0) length = std::min(length, max_range);
      cells += 1 + 1.7320508075688772 * length / params_.grid.resolution_m;
    }
    require_memory(cells * kBytesPerRayCell,
                   "octomap's ray update (scan " + std::to_string(counts_.scans + 1) + ": " +
                       std::to_string(cloud.size()) + " rays crossing about " + std::to_string(uint64_t(cells)) +
                       " cells)",
                   "give a shorter --max-range, a coarser --resolution or --ds (or raise --max-memory)");
  }

  void finish() override {}

  void write_file(const std::filesystem::path& file, TreeValues) override {
    check_output(file);
    // writeBinary turns the tree into max-likelihood states: write a copy, keep the probabilities.
    octomap::OcTree copy(tree_);
    write_tree_atomically(file, copy, map_format_from_path(file) == MapFormat::kOctomapBinary);
  }

  // OctoMap's probability; a log-odds cell has no variance, so none is given.
  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override {
    const octomap::OcTreeNode* node = tree_.search(x, y, z);
    if (!node) return std::nullopt;
    CellEstimate e;
    e.occupancy = node->getOccupancy();
    return e;
  }

  const BuildParams& params() const override { return params_; }
  const BuildCounts& counts() const override { return counts_; }
  const InsertTiming& timing() const override { return timing_; }
  BackendInfo backend() const override { return {"octomap", "liboctomap (single thread)", 1, ""}; }
  uint64_t blocks_touched() override { return 0; }

  uint64_t known_cells() override {
    const unsigned max_depth = tree_.getTreeDepth();
    uint64_t cells = 0;
    for (auto it = tree_.begin_leafs(), end = tree_.end_leafs(); it != end; ++it)
      cells += uint64_t{1} << (3 * (max_depth - it.getDepth()));
    return cells;
  }

 private:
  BuildParams params_;
  octomap::OcTree tree_;
  BuildCounts counts_;
  InsertTiming timing_;
};

}  // namespace

std::unique_ptr<MappingMethod> make_octomap_method(const BuildParams& params, const MethodParams& method_params) {
  return std::make_unique<OctomapMethod>(params, octomap_params(method_params));
}

}  // namespace bgkmap
