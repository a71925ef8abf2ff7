// Parameters of a map build, with their defaults and units. Names match the CLI flags
// (--ell -> ell_m) and the JSON report's "params" keys (see params_io.hpp).
#pragma once

#include <cstdint>
#include <string>

namespace bgkmap {

enum class KernelType { kSparse = 0, kBox = 1 };

const char* to_string(KernelType type);
// Throws std::invalid_argument naming the accepted values.
KernelType kernel_type_from_string(const std::string& name);

// What a return farther than the max range becomes: kFree, a free beam of max-range length and no
// hit (OctoMap's convention: the beam saw that much free space); kDrop, nothing (la3dm's, for
// comparisons with it).
enum class BeyondRange { kFree = 0, kDrop = 1 };

const char* to_string(BeyondRange policy);
// Throws std::invalid_argument naming the accepted values.
BeyondRange beyond_range_from_string(const std::string& name);

// How the BGK maps take a scan's pose uncertainty (docs/ALGORITHM.md, "Pose uncertainty"):
// "submap", the expected sub-map (the moment-matched mixture of the scan's plain updates under
// each sigma point), or "kernel", the expected kernel (the kernel averaged over the sigma points).
enum class PoseFusion { kExpectedSubmap = 0, kExpectedKernel = 1 };

const char* to_string(PoseFusion fusion);
// Throws std::invalid_argument naming the accepted values.
PoseFusion pose_fusion_from_string(const std::string& name);

// The world frame a KITTI sequence is mapped in: the velodyne frame of its first scan (z up, the
// default) or KITTI's camera-0 frame of its first scan (y down, z forward), as poses.txt is.
enum class KittiFrame { kVelodyne = 0, kCamera = 1 };

const char* to_string(KittiFrame frame);
// Throws std::invalid_argument naming the accepted values.
KittiFrame kitti_frame_from_string(const std::string& name);

// Geometry of the block grid: blocks of 2^(block_depth-1) cells per side.
struct GridParams {
  double resolution_m = 0.1;
  int block_depth = 4;  // 4 -> 8x8x8 cells per block, as la3dm's test-data octree leaves

  int cells_per_side() const { return 1 << (block_depth - 1); }
  int cells_per_block() const { return cells_per_side() * cells_per_side() * cells_per_side(); }
  double block_size_m() const { return resolution_m * cells_per_side(); }
};

struct KernelParams {
  KernelType type = KernelType::kSparse;
  float ell_m = 0.2f;   // length scale l: the sparse kernel is zero at and beyond it
  float sigma0 = 0.1f;  // kernel scale: weight of an observation at distance 0

  // Radius beyond which an observation cannot touch a cell centre. The box kernel reaches the
  // cell's corners, a half diagonal away (padded so that points on a corner are never missed).
  float support_radius_m(double resolution_m) const;
  // 1 / ell^2 as the one float every back end hands to bgk_sparse_kernel_d2.
  float inverse_ell_squared() const { return static_cast<float>(1.0 / (double(ell_m) * double(ell_m))); }
};

struct PriorParams {
  float alpha0 = 0.001f;
  float beta0 = 0.001f;
};

// The constant per-scan pose uncertainty of --pose-sigma (pose_covariance.hpp gives the
// convention): independent standard deviations.
struct PoseSigma {
  double xy_m = 0;            // translation along x and along y (each)
  double yaw_rad = 0;         // rotation about z
  double z_m = 0;             // translation along z
  double roll_pitch_rad = 0;  // rotation about x and about y (each)

  bool is_zero() const { return xy_m == 0 && yaw_rad == 0 && z_m == 0 && roll_pitch_rad == 0; }
};

// --ds is 0 (off) or at least this fraction of the resolution (BuildParams::validate).
constexpr double kMinDownsampleFraction = 0.01;

struct PreprocessParams {
  double downsample_m = 0.0;  // --ds: voxel-grid leaf size, 0 = off
  double max_range_m = 0.0;   // returns beyond it add no hit, only a free beam of this length; 0 = no limit
  BeyondRange beyond_range = BeyondRange::kFree;  // or drop such returns altogether
  double end_margin_m = 0.1;  // the free segment stops this far short of the hit (docs/RESULTS.md: chosen by score)
  // --frame sensor: points are in the sensor frame, transformed by the scan pose (the formats that
  // put their points in the world themselves are not: Scan::points_in_world_frame).
  bool apply_viewpoint = false;
  // --kitti-frame: the frame KITTI sequences are mapped in (it fixes what the map's cells mean).
  KittiFrame kitti_frame = KittiFrame::kVelodyne;
  // A planar map (--2d): every point and the origin are moved onto the plane z = plane_z_m, the
  // centre plane of one layer of cells (BuildParams::set_planar), and the map keeps that layer
  // only, so kernel distances are distances in the plane.
  bool planar = false;
  double plane_z_m = 0.0;
  // --pose-sigma: the pose uncertainty of every scan that brings none of its own
  // (Scan::pose_covariance); zero: none. The BGK maps then take it by `pose_fusion`
  // (docs/ALGORITHM.md, "Pose uncertainty").
  PoseSigma pose_sigma;
  PoseFusion pose_fusion = PoseFusion::kExpectedSubmap;  // --pose-fusion
};

struct ClassifyParams {
  float occupied_threshold = 0.7f;  // mean above: occupied
  float free_threshold = 0.3f;      // mean below: free
  float var_threshold = 0.1f;       // variance above: unknown, whatever the mean
};

// Everything that defines a map build.
struct BuildParams {
  GridParams grid;
  KernelParams kernel;
  PriorParams prior;
  PreprocessParams preprocess;
  ClassifyParams classify;

  // Throws std::invalid_argument with a one-line reason when a value is out of range.
  void validate() const;
  // validate(), and for the methods that pair points with blocks by the kernel's support (the
  // Mapper's, gpoctomap) that --ell reaches few enough blocks.
  void check_kernel_reach() const;

  // Makes the map planar in the layer of cells holding height z_m (its centre plane becomes
  // preprocess.plane_z_m); set the resolution first.
  void set_planar(double z_m);
  // The layer's cell index along z (planar maps).
  int32_t planar_layer() const;
};

}  // namespace bgkmap
