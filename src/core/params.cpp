#include "bgkmap/core/params.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace bgkmap {

const char* to_string(KernelType type) {
  switch (type) {
    case KernelType::kSparse: return "sparse";
    case KernelType::kBox: return "box";
  }
  return "?";
}

KernelType kernel_type_from_string(const std::string& name) {
  if (name == "sparse") return KernelType::kSparse;
  if (name == "box") return KernelType::kBox;
  throw std::invalid_argument("unknown kernel '" + name + "' (expected sparse or box)");
}

const char* to_string(BeyondRange policy) {
  switch (policy) {
    case BeyondRange::kFree: return "free";
    case BeyondRange::kDrop: return "drop";
  }
  return "?";
}

BeyondRange beyond_range_from_string(const std::string& name) {
  if (name == "free") return BeyondRange::kFree;
  if (name == "drop") return BeyondRange::kDrop;
  throw std::invalid_argument("unknown beyond-range policy '" + name + "' (expected free or drop)");
}

float KernelParams::support_radius_m(double resolution_m) const {
  if (type == KernelType::kBox) return static_cast<float>(resolution_m * 0.8660254037844386 * 1.001);
  return ell_m;
}

namespace {
void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}
bool finite_positive(double v) { return std::isfinite(v) && v > 0; }
}  // namespace

void BuildParams::validate() const {
  require(finite_positive(grid.resolution_m), "resolution must be a positive number of metres");
  require(grid.block_depth >= 1 && grid.block_depth <= 7, "block depth must be between 1 and 7");
  require(finite_positive(kernel.ell_m), "ell must be a positive number of metres");
  require(finite_positive(kernel.sigma0), "sigma0 must be positive");
  require(finite_positive(prior.alpha0) && finite_positive(prior.beta0), "prior alpha and beta must be positive");
  require(std::isfinite(preprocess.downsample_m) && preprocess.downsample_m >= 0, "ds must be >= 0 (0 = off)");
  require(std::isfinite(preprocess.max_range_m) && preprocess.max_range_m >= 0, "max range must be >= 0 (0 = no limit)");
  require(std::isfinite(preprocess.end_margin_m) && preprocess.end_margin_m >= 0, "end margin must be >= 0");
  require(classify.free_threshold >= 0 && classify.free_threshold <= classify.occupied_threshold &&
              classify.occupied_threshold <= 1,
          "thresholds must satisfy 0 <= free-threshold <= occupied-threshold <= 1");
  require(classify.var_threshold > 0, "var threshold must be positive");
}

}  // namespace bgkmap
