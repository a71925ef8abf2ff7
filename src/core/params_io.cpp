#include "bgkmap/core/params_io.hpp"

#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "core/float_decimal.hpp"
#include "core/json_integer.hpp"

namespace bgkmap {


nlohmann::json params_to_json(const BuildParams& p) {
  nlohmann::json j = {
      {"resolution", p.grid.resolution_m},
      {"block_depth", p.grid.block_depth},
      {"kernel", to_string(p.kernel.type)},
      {"ell", as_decimal(p.kernel.ell_m)},
      {"sigma0", as_decimal(p.kernel.sigma0)},
      {"prior_alpha", as_decimal(p.prior.alpha0)},
      {"prior_beta", as_decimal(p.prior.beta0)},
      {"ds", p.preprocess.downsample_m},
      {"max_range", p.preprocess.max_range_m},
      {"beyond_range", to_string(p.preprocess.beyond_range)},
      {"end_margin", p.preprocess.end_margin_m},
      {"apply_viewpoint", p.preprocess.apply_viewpoint},
      {"occupied_threshold", as_decimal(p.classify.occupied_threshold)},
      {"free_threshold", as_decimal(p.classify.free_threshold)},
      {"var_threshold", as_decimal(p.classify.var_threshold)},
  };
  // Only planar maps carry the keys, so 3-D maps' files and reports stay as they were.
  if (p.preprocess.planar) {
    j["planar"] = true;
    j["plane_z"] = p.preprocess.plane_z_m;
  }
  // Likewise only maps built under a constant pose uncertainty: [xy, yaw, z, roll_pitch].
  const PoseSigma& ps = p.preprocess.pose_sigma;
  if (!ps.is_zero()) j["pose_sigma"] = {ps.xy_m, ps.yaw_rad, ps.z_m, ps.roll_pitch_rad};
  // And only maps that asked for the expected kernel instead of the default expected sub-map.
  if (p.preprocess.pose_fusion != PoseFusion::kExpectedSubmap) j["pose_fusion"] = to_string(p.preprocess.pose_fusion);
  // And only maps of KITTI sequences in the camera frame.
  if (p.preprocess.kitti_frame != KittiFrame::kVelodyne) j["kitti_frame"] = to_string(p.preprocess.kitti_frame);
  return j;
}

namespace {
template <typename T>
void read_key(const nlohmann::json& j, const char* key, T& out) {
  const auto it = j.find(key);
  if (it == j.end()) return;
  if constexpr (std::is_integral_v<T> && !std::is_same_v<T, bool>)
    if (!json_integer_fits<T>(*it))
      throw std::invalid_argument(std::string("parameter '") + key + "' must be an integer within its type's range");
  try {
    out = it->get<T>();
  } catch (const nlohmann::json::exception&) {
    throw std::invalid_argument(std::string("parameter '") + key + "' has the wrong type");
  }
}
}  // namespace

BuildParams params_from_json(const nlohmann::json& j) {
  if (!j.is_object()) throw std::invalid_argument("parameters must be a JSON object");
  static const char* const known[] = {"resolution", "block_depth", "kernel", "ell", "sigma0",
                                      "prior_alpha", "prior_beta", "ds", "max_range", "beyond_range", "end_margin",
                                      "apply_viewpoint", "occupied_threshold", "free_threshold", "var_threshold",
                                      "planar", "plane_z", "pose_sigma", "pose_fusion", "kitti_frame"};
  for (const auto& item : j.items()) {
    bool ok = false;
    for (const char* k : known) ok = ok || item.key() == k;
    if (!ok) throw std::invalid_argument("unknown parameter '" + item.key() + "'");
  }
  BuildParams p;
  read_key(j, "resolution", p.grid.resolution_m);
  read_key(j, "block_depth", p.grid.block_depth);
  std::string kernel = to_string(p.kernel.type);
  read_key(j, "kernel", kernel);
  p.kernel.type = kernel_type_from_string(kernel);
  read_key(j, "ell", p.kernel.ell_m);
  read_key(j, "sigma0", p.kernel.sigma0);
  read_key(j, "prior_alpha", p.prior.alpha0);
  read_key(j, "prior_beta", p.prior.beta0);
  read_key(j, "ds", p.preprocess.downsample_m);
  read_key(j, "max_range", p.preprocess.max_range_m);
  std::string beyond_range = to_string(p.preprocess.beyond_range);
  read_key(j, "beyond_range", beyond_range);
  p.preprocess.beyond_range = beyond_range_from_string(beyond_range);
  read_key(j, "end_margin", p.preprocess.end_margin_m);
  read_key(j, "apply_viewpoint", p.preprocess.apply_viewpoint);
  read_key(j, "occupied_threshold", p.classify.occupied_threshold);
  read_key(j, "free_threshold", p.classify.free_threshold);
  read_key(j, "var_threshold", p.classify.var_threshold);
  read_key(j, "planar", p.preprocess.planar);
  read_key(j, "plane_z", p.preprocess.plane_z_m);
  std::vector<double> pose_sigma;
  read_key(j, "pose_sigma", pose_sigma);
  if (!pose_sigma.empty()) {
    if (pose_sigma.size() != 4) throw std::invalid_argument("parameter 'pose_sigma' must be [xy, yaw, z, roll_pitch]");
    p.preprocess.pose_sigma = {pose_sigma[0], pose_sigma[1], pose_sigma[2], pose_sigma[3]};
  }
  std::string pose_fusion = to_string(p.preprocess.pose_fusion);
  read_key(j, "pose_fusion", pose_fusion);
  p.preprocess.pose_fusion = pose_fusion_from_string(pose_fusion);
  std::string kitti_frame = to_string(p.preprocess.kitti_frame);
  read_key(j, "kitti_frame", kitti_frame);
  p.preprocess.kitti_frame = kitti_frame_from_string(kitti_frame);
  return p;
}

}  // namespace bgkmap
