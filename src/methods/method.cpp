// Choosing a method by name, and the checks on the parameters only some methods read.
#include "bgkmap/methods/method.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "core/number_text.hpp"
#include "methods/bgkl/bgk_map_method.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/bhm/bhm_method.hpp"
#include "methods/bhm/bhm_model.hpp"
#include "methods/counting/counting_method.hpp"
#include "methods/gpoctomap/gpoctomap_method.hpp"
#include "methods/gpom/gpom_method.hpp"
#include "methods/octomap/octomap_method.hpp"

namespace bgkmap {

namespace {

// The largest values taken. Labels are +-1: far past these the GP's squares and products
// overflow (--gp-signal 1e300 gave an empty map) and nearer, the data are already swamped; a
// range noise past 100 m is no sensor's.
constexpr double kMaxGpNoise = 1e3;
constexpr double kMaxGpSignal = 1e6;
constexpr double kMaxGpRangeSigmaM = 100;

// A bound as the messages print it: 1e+06, 100.

}  // namespace

void MethodParams::validate() const {
  // Every bound is false for NaN. Infinite or overflowing values are refused here: past these
  // bounds the methods' products and squares overflow, and the map came out empty.
  const auto positive = [](double v) { return v > 0 && std::isfinite(v); };
  const auto within = [](double v, double lo, double hi) { return v >= lo && v <= hi; };
  if (!positive(free_resolution_m)) throw std::invalid_argument("free-resolution must be > 0 and finite");
  const auto probability = [](double p) { return p > 0 && p < 1; };
  if (!probability(prob_hit) || !(prob_hit > 0.5)) throw std::invalid_argument("prob-hit must be in (0.5, 1)");
  if (!probability(prob_miss) || !(prob_miss < 0.5)) throw std::invalid_argument("prob-miss must be in (0, 0.5)");
  if (!probability(clamp_min) || !probability(clamp_max) || !(clamp_min < clamp_max))
    throw std::invalid_argument("clamp-min and clamp-max must satisfy 0 < clamp-min < clamp-max < 1");
  if (!(gp_noise > 0 && gp_noise <= kMaxGpNoise))
    throw std::invalid_argument("gp-noise must be in (0, " + number_text(kMaxGpNoise) + "] (a standard deviation of labels +-1)");
  if (!positive(gp_squash)) throw std::invalid_argument("gp-squash must be > 0 and finite");
  if (gp_covariance != "matern" && gp_covariance != "sparse" && gp_covariance != "se" && gp_covariance != "nn")
    throw std::invalid_argument("gp-covariance must be matern, sparse, se or nn, not '" + gp_covariance + "'");
  if (!positive(gp_length_m)) throw std::invalid_argument("gp-length must be > 0 and finite");
  if (!(gp_signal_var > 0 && gp_signal_var <= kMaxGpSignal))
    throw std::invalid_argument("gp-signal must be in (0, " + number_text(kMaxGpSignal) + "]");
  if (!within(gp_range_sigma, 0, kMaxGpRangeSigmaM))
    throw std::invalid_argument("gp-range-sigma must be in [0, " + number_text(kMaxGpRangeSigmaM) + "] m");
  if (!(gp_bearing_sigma >= 0 && gp_bearing_sigma < 0.5))
    throw std::invalid_argument("gp-bearing-sigma must be in [0, 0.5) rad");
  if (!(gp_neighbours >= 1 && gp_neighbours <= 1000 && gp_neighbours == std::floor(gp_neighbours)))
    throw std::invalid_argument("gp-neighbours must be a whole number in [1, 1000]");
  const auto whole = [](double v) { return v == std::floor(v); };
  if (!positive(bhm_spacing)) throw std::invalid_argument("bhm-spacing must be > 0 and finite");
  if (!(bhm_gamma >= 0 && std::isfinite(bhm_gamma)))
    throw std::invalid_argument("bhm-gamma must be > 0 and finite, or 0: chosen by the evidence");
  if (!(bhm_evidence_scans >= 1 && bhm_evidence_scans <= 1000 && whole(bhm_evidence_scans)))
    throw std::invalid_argument("bhm-evidence-scans must be a whole number in [1, 1000]");
  if (!(bhm_support_var >= 0 && std::isfinite(bhm_support_var)))
    throw std::invalid_argument("bhm-support-var must be >= 0 and finite");
  if (!(bhm_support_side >= 0 && std::isfinite(bhm_support_side)))
    throw std::invalid_argument("bhm-support-side must be >= 0 and finite");
  if (bhm_support_var > 0 && bhm_support_side > 0)
    throw std::invalid_argument("bhm-support-var (Gaussian supports) and bhm-support-side (rectangles) exclude each other");
  if (!within(bhm_prior_var, kMinBhmPriorVar, kMaxBhmPriorVar))
    throw std::invalid_argument("bhm-prior-var must be in [" + number_text(kMinBhmPriorVar) + ", " +
                                number_text(kMaxBhmPriorVar) + "]");
  if (!(bhm_em_iterations >= 1 && bhm_em_iterations <= 100 && whole(bhm_em_iterations)))
    throw std::invalid_argument("bhm-em-iterations must be a whole number in [1, 100]");
  if (!(bhm_block_side >= 0 && bhm_block_side <= 64 && whole(bhm_block_side)))
    throw std::invalid_argument("bhm-block-side must be a whole number in [0, 64]");
  if (bhm_free != "points" && bhm_free != "beams")
    throw std::invalid_argument("bhm-free must be points or beams, not '" + bhm_free + "'");
  if (gp_input_correlation != "independent" && gp_input_correlation != "scan" && gp_input_correlation != "trajectory")
    throw std::invalid_argument("gp-input-correlation must be independent, scan or trajectory, not '" +
                                gp_input_correlation + "'");
  if (gp_hyperparameters != "given" && gp_hyperparameters != "learn")
    throw std::invalid_argument("gp-hyperparameters must be given or learn, not '" + gp_hyperparameters + "'");
  if (!(wgp_terms >= 0 && wgp_terms <= 10 && wgp_terms == std::floor(wgp_terms)))
    throw std::invalid_argument("wgp-terms must be a whole number in [0, 10]");
}

namespace {

using MethodFactory = std::unique_ptr<MappingMethod> (*)(const BuildParams&, const MethodParams&,
                                                         const BackendOptions&);

// Every method `--method` accepts, in the order --help lists them: a new method is its own file
// and one line here.
struct MethodEntry {
  const char* name;
  MethodFactory make;
};
const MethodEntry kMethods[] = {
    {"bgkl",
     [](const BuildParams& p, const MethodParams&, const BackendOptions& b) {
       return make_bgkl_method(std::make_unique<Mapper>(p, make_integrator(b)));
     }},
    {"bgk",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
       return make_bgk_method(p, m, make_integrator(b));
     }},
    {"counting",
     [](const BuildParams& p, const MethodParams&, const BackendOptions&) { return make_counting_method(p); }},
    {"octomap",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions&) { return make_octomap_method(p, m); }},
    {"gpoctomap",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
       p.check_kernel_reach();
       return make_gpoctomap_method(p, m, b.threads);
     }},
    {"gpom",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
       return make_gpom_method(p, m, b);
     }},
    {"bhm",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) { return make_bhm_method(p, m, b); }},
    {"wgpom",
     [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
       return make_wgpom_method(p, m, b);
     }},
};

}  // namespace

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const MethodEntry& entry : kMethods) out.push_back(entry.name);
    return out;
  }();
  return names;
}

namespace {
std::string pose_uncertainty_refusal(const std::string& name) {
  return "the method " + name + " does not use a pose uncertainty (--pose-sigma, --pose-covariance, poses with a "
         "covariance); bgkl, bgk, gpom and wgpom do";
}
}  // namespace

void MappingMethod::check_pose_uncertainty(const PreparedScan& prepared) const {
  if (prepared.pose_covariance && !uses_pose_uncertainty()) throw std::invalid_argument(pose_uncertainty_refusal(name()));
}

std::unique_ptr<MappingMethod> make_method(const std::string& name, const BuildParams& params,
                                           const MethodParams& method_params, const BackendOptions& backend) {
  method_params.validate();
  check_thread_count(backend.threads);
  for (const MethodEntry& entry : kMethods)
    if (name == entry.name) {
      std::unique_ptr<MappingMethod> method = entry.make(params, method_params, backend);
      if (!params.preprocess.pose_sigma.is_zero() && !method->uses_pose_uncertainty())
        throw std::invalid_argument(pose_uncertainty_refusal(name));
      return method;
    }
  std::string accepted;
  for (const std::string& known : method_names()) accepted += (accepted.empty() ? "" : ", ") + known;
  throw std::invalid_argument("unknown method '" + name + "' (expected one of " + accepted + ")");
}

}  // namespace bgkmap
