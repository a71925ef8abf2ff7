#include "bgkmap/core/params.hpp"

#include "bgkmap/core/build_param_table.hpp"
#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "core/number_text.hpp"

#include <cmath>
#include <cstddef>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace bgkmap {

namespace {

// The names of an enum's values, for the functions below: one table per enum.
template <class Enum>
using EnumNames = std::pair<Enum, const char*>;
constexpr EnumNames<KernelType> kKernelTypeNames[] = {{KernelType::kSparse, "sparse"}, {KernelType::kBox, "box"}};
constexpr EnumNames<BeyondRange> kBeyondRangeNames[] = {{BeyondRange::kFree, "free"}, {BeyondRange::kDrop, "drop"}};
constexpr EnumNames<PoseFusion> kPoseFusionNames[] = {{PoseFusion::kExpectedSubmap, "submap"},
                                                       {PoseFusion::kExpectedKernel, "kernel"}};
constexpr EnumNames<KittiFrame> kKittiFrameNames[] = {{KittiFrame::kVelodyne, "velodyne"},
                                                       {KittiFrame::kCamera, "camera"}};

template <class Enum, size_t N>
const char* name_of(const EnumNames<Enum> (&names)[N], Enum value) {
  for (const auto& [v, name] : names)
    if (v == value) return name;
  return "?";
}

// The value called `name`; otherwise "unknown <what> 'name' (expected a, b or c)".
template <class Enum, size_t N>
Enum value_named(const EnumNames<Enum> (&names)[N], const std::string& name, const char* what) {
  std::string expected;
  for (size_t i = 0; i < N; ++i) {
    if (name == names[i].second) return names[i].first;
    expected += std::string(i == 0 ? "" : i + 1 == N ? " or " : ", ") + names[i].second;
  }
  throw std::invalid_argument(std::string("unknown ") + what + " '" + name + "' (expected " + expected + ")");
}

template <class Enum, size_t N>
std::vector<std::string> names(const EnumNames<Enum> (&table)[N]) {
  std::vector<std::string> out;
  for (const auto& entry : table) out.push_back(entry.second);
  return out;
}

}  // namespace

template <>
std::vector<std::string> value_names<KernelType>() { return names(kKernelTypeNames); }
template <>
std::vector<std::string> value_names<BeyondRange>() { return names(kBeyondRangeNames); }
template <>
std::vector<std::string> value_names<PoseFusion>() { return names(kPoseFusionNames); }
template <>
std::vector<std::string> value_names<KittiFrame>() { return names(kKittiFrameNames); }

const char* to_string(KernelType type) { return name_of(kKernelTypeNames, type); }

KernelType kernel_type_from_string(const std::string& name) { return value_named(kKernelTypeNames, name, "kernel"); }

const char* to_string(BeyondRange policy) { return name_of(kBeyondRangeNames, policy); }

BeyondRange beyond_range_from_string(const std::string& name) {
  return value_named(kBeyondRangeNames, name, "beyond-range policy");
}

const char* to_string(PoseFusion fusion) { return name_of(kPoseFusionNames, fusion); }

PoseFusion pose_fusion_from_string(const std::string& name) { return value_named(kPoseFusionNames, name, "pose fusion"); }

const char* to_string(KittiFrame frame) { return name_of(kKittiFrameNames, frame); }

KittiFrame kitti_frame_from_string(const std::string& name) { return value_named(kKittiFrameNames, name, "KITTI frame"); }

float KernelParams::support_radius_m(double resolution_m) const {
  if (type == KernelType::kBox) return static_cast<float>(resolution_m * 0.8660254037844386 * 1.001);
  return ell_m;
}

namespace {
void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}
// A point's kernel may reach this many blocks on each side (17^3 = 4913 blocks, 2.5 M cells
// a point); beyond, a scan's work and memory grow past anything useful (--ell 100 at
// --resolution 0.1 reached 125 and ran out of memory).
constexpr double kMaxSupportBlocks = 8;
}  // namespace

void BuildParams::validate() const {
  for (const BuildParam& p : build_param_table())  // each value alone: its range
    if (p.spec.kind != ParamKind::kChoice && !p.spec.accepts(p.number(*this))) throw rejection(p.spec);
  // A voxel filter far finer than the cells changes nothing they hold, and below float's precision
  // it merges points it cannot tell apart (1e-30 m kept 2 of 3,500).
  if (preprocess.downsample_m != 0 && preprocess.downsample_m < grid.resolution_m * kMinDownsampleFraction)
    throw ParamError("{ds} " + number_text(preprocess.downsample_m) + " m is below " + number_text(kMinDownsampleFraction) +
                     " of {resolution} " + number_text(grid.resolution_m) + " m (0 turns the voxel filter off)");
  if (classify.free_threshold > classify.occupied_threshold)
    throw ParamError("{free-threshold} must not exceed {occupied-threshold}");
  const PoseSigma& ps = preprocess.pose_sigma;
  const std::string pose_problem = pose_sigma_problem(ps);
  if (!pose_problem.empty()) throw ParamError("{pose-sigma}: " + pose_problem);
  if (!ps.is_zero() && kernel.type != KernelType::kSparse)
    throw ParamError("a pose uncertainty ({pose-sigma}) needs the sparse kernel ({kernel} sparse; the box kernel counts, "
                     "it has no expectation to take)");
  if (preprocess.planar) {
    const double layer = preprocess.plane_z_m / grid.resolution_m - 0.5;
    require(std::fabs(layer - std::round(layer)) < 1e-6 && std::fabs(layer) < 1e9,
            "the plane of a 2-D map must be the centre plane of a layer of cells (BuildParams::set_planar)");
  }
}

void BuildParams::check_kernel_reach() const {
  validate();
  // Each point is paired with every block within the kernel's support: (2 reach + 1)^3 blocks.
  const double reach_blocks = kernel.support_radius_m(grid.resolution_m) / grid.block_size_m();
  if (reach_blocks > kMaxSupportBlocks)
    throw ParamError("{ell} " + number_text(kernel.ell_m) + " m reaches " + number_text(std::ceil(reach_blocks)) +
                     " blocks of " + number_text(grid.block_size_m()) + " m ({resolution} " +
                     number_text(grid.resolution_m) + " x " + std::to_string(grid.cells_per_side()) +
                     " cells) on each side of a point; at most " + number_text(kMaxSupportBlocks) +
                     ": lower {ell} or raise {resolution}");
}

void BuildParams::set_planar(double z_m) {
  preprocess.planar = true;
  preprocess.plane_z_m = (std::floor(z_m / grid.resolution_m) + 0.5) * grid.resolution_m;
}

int32_t BuildParams::planar_layer() const {
  return static_cast<int32_t>(std::floor(preprocess.plane_z_m / grid.resolution_m));
}

}  // namespace bgkmap
