// --method bhm: the Bayesian Hilbert map, and its parameters.
#include <stdexcept>

#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/bhm/bhm_method.hpp"
#include "methods/bhm/bhm_model.hpp"

namespace bgkmap {

namespace {

const ParamSpec& spacing() {
  static const ParamSpec s = ParamSpec::number("bhm-spacing", 0.25, above(0), unbounded(),
                                               "Distance between neighbouring hinge points (m; the paper gives none for the Intel log)")
                                 .in_unit("m");
  return s;
}
const ParamSpec& gamma() {
  static const ParamSpec s =
      ParamSpec::number("bhm-gamma", 20.0, above(0), unbounded(),
                        "RBF features exp(-gamma |x - h|^2), gamma in 1/m^2 (the paper's G^-1; paper mode: 6.667, its Intel G = "
                        "0.15 I); 0: chosen by the evidence (the variational "
                        "lower bound of the first --bhm-evidence-scans scans) among 1.25 / spacing^2 times 2^(k/2), k in "
                        "[-6, 6]")
          .in_unit("1/m^2")
          .with_zero_meaning("chosen by the evidence");
  return s;
}
const ParamSpec& evidence_scans() {
  static const ParamSpec s = ParamSpec::whole_number(
      "bhm-evidence-scans", 1, 1, 1000,
      "With --bhm-gamma 0, the scans whose evidence chooses gamma (each candidate learns them)");
  return s;
}
const ParamSpec& support_var() {
  static const ParamSpec s =
      ParamSpec::number("bhm-support-var", 0, at_least(0), unbounded(),
                        "> 0: Gaussian supports (the paper's eq. 13), each hinge spread as N(h, var I) (m^2); 0: plain RBF, "
                        "the paper's Intel setting")
          .in_unit("m^2");
  return s;
}
const ParamSpec& support_side() {
  static const ParamSpec s = ParamSpec::number("bhm-support-side", 0, at_least(0), unbounded(),
                                               "> 0: rectangle supports (the paper's eq. 14), each hinge spread uniformly "
                                               "over a square (cube in 3-D) of this side (m); 0: plain RBF, the paper's "
                                               "Intel setting")
                                 .in_unit("m");
  return s;
}
const ParamSpec& prior_var() {
  static const ParamSpec s = ParamSpec::number("bhm-prior-var", 1.0, at_least(kMinBhmPriorVar),
                                               at_most(kMaxBhmPriorVar), "Prior variance of every weight (mean 0; paper mode: 1e4, the paper's)");
  return s;
}
const ParamSpec& bias() {
  static const ParamSpec s = ParamSpec::choice(
      "bhm-bias", {"none", "global"}, "none",
      "A bias feature phi_0(x) = 1 (the paper's eq. 1): none, or global, one weight shared by the whole map, "
      "its own factor of the posterior (paper mode: global)");
  return s;
}
const ParamSpec& mode() {
  static const ParamSpec s =
      ParamSpec::choice("bhm-mode", {"default", "paper"}, "default",
                        "paper: the paper's values (Senanayake & Ramos 2018) for the parameters not given: "
                        "--bhm-prior-var 1e4, --bhm-bias global, --bhm-gamma 6.667 (G = 0.15 I, its Intel value); "
                        "default: bgkmap's")
          .with_preset("paper", {{"bhm-prior-var", kPaperBhmPriorVar, ""},
                                 {"bhm-bias", 0, "global"},
                                 {"bhm-gamma", kPaperBhmGamma, ""}});
  return s;
}
const ParamSpec& em_iterations() {
  static const ParamSpec s = ParamSpec::whole_number("bhm-em-iterations", 3, 1, 100,
                                                     "Variational EM iterations (xi, then the posterior) per scan (the paper states no "
                                                     "number: it converges 'in 1-2 iterations')");
  return s;
}
const ParamSpec& block_side() {
  static const ParamSpec s = ParamSpec::whole_number(
      "bhm-block-side", 0, 0, 64, "Supports per side of a block with its own full covariance (0: 8 in 2-D, 4 in 3-D; "
      "the paper has one full covariance, bgkmap's approximation)");
  return s;
}
const ParamSpec& free_space() {
  static const ParamSpec s = ParamSpec::choice(
      "bhm-free", {"points", "beams"}, "points",
      "Free space as points sampled every --free-resolution along each beam (the paper's data, which it "
      "draws uniformly at random), or as beams (bgkmap's, not the paper's eq. 11-12): the bound integrated along "
      "each beam with the features' exact line integrals (erf; 2-D maps), worth 1 / --free-resolution points per metre");
  return s;
}

void check(const MethodParams& m) {
  if (m.choice("bhm-bias") != "none" && m.choice("bhm-free") == "beams")
    throw std::invalid_argument("--bhm-bias global (--bhm-mode paper's) needs --bhm-free points: a bias with free beams is "
                                "not implemented; give --bhm-bias none or --bhm-free points");
  if (m.number("bhm-support-var") > 0 && m.number("bhm-support-side") > 0)
    throw std::invalid_argument("bhm-support-var (Gaussian supports) and bhm-support-side (rectangles) exclude each other");
}

}  // namespace

BhmMethodParams bhm_method_params(const MethodParams& m) {
  BhmMethodParams p;
  p.free_resolution_m = m.number("free-resolution");
  p.bhm_spacing = m.number("bhm-spacing");
  p.bhm_gamma = m.number("bhm-gamma");
  p.bhm_support_var = m.number("bhm-support-var");
  p.bhm_prior_var = m.number("bhm-prior-var");
  p.bhm_evidence_scans = m.whole("bhm-evidence-scans");
  p.bhm_support_side = m.number("bhm-support-side");
  p.bhm_em_iterations = m.whole("bhm-em-iterations");
  p.bhm_block_side = m.whole("bhm-block-side");
  p.bhm_free = m.choice("bhm-free");
  p.bhm_bias = m.choice("bhm-bias") == "global";
  return p;
}

const MethodDescriptor& bhm_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "bhm";
    d.summary = "Bayesian Hilbert map: variational logistic regression on RBF features, sequential over scans";
    d.params = {&free_resolution_param(), &spacing(),      &gamma(),         &evidence_scans(), &support_var(),
                &support_side(),          &prior_var(),    &em_iterations(), &block_side(),     &free_space(),
                &bias(),                  &mode()};
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the logit a = phi(x)^T w under the weights' posterior; occupancy is "
                 "sigma(mean / sqrt(1 + pi variance / 8))";
    d.check = check;
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) { return make_bhm_method(p, m, b); };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
