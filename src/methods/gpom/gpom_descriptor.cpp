// --method gpom: a GP per query on its nearest hits and beams; its parameters, which wgpom reads too.
#include <vector>

#include "bgkmap/methods/method_descriptor.hpp"
#include "methods/gp/gp_params.hpp"
#include "methods/gpom/gpom_method.hpp"

namespace bgkmap {

namespace {

// Past this signal variance the GP's squares and products overflow (--gp-signal 1e300 gave an
// empty map); a range noise past 100 m is no sensor's.
constexpr double kMaxGpSignal = 1e6;
constexpr double kMaxGpRangeSigmaM = 100;

const ParamSpec& gp_covariance() {
  static const ParamSpec s = ParamSpec::choice(
      "gp-covariance", {"matern", "sparse", "se", "nn"}, "matern",
      "Covariance function, matern (nu = 3/2), sparse (the BGK kernel), se (squared exponential; "
      "its expected kernel under --pose-fusion kernel is closed form) or nn (the IJRR paper's neural-network "
      "covariance, bias s0^2 = 1, each local model centred at its query; CPU only; not with the expected kernel: "
      "--pose-fusion kernel, --gp-range-sigma, --gp-bearing-sigma)");
  return s;
}
const ParamSpec& gp_length() {
  static const ParamSpec s =
      ParamSpec::number("gp-length", 0.5, above(0), unbounded(), "Covariance length scale (m)").in_unit("m");
  return s;
}
const ParamSpec& gp_signal() {
  static const ParamSpec s = ParamSpec::number(
      "gp-signal", 1.0, above(0), at_most(kMaxGpSignal),
      "Covariance signal variance s2 (k(x, x) but for nn, whose k(x, x) is s2 (2/pi) asin(2/3) at the query)");
  return s;
}
const ParamSpec& gp_neighbours() {
  static const ParamSpec s =
      ParamSpec::whole_number("gp-neighbours", 0, 1, 1000,
                              "Each query's local model holds this many nearest hits and this many nearest beams; "
                              "0: the mode's, 30, or the paper's 15 under --gp-mode paper")
          .with_zero_meaning("the mode's count");
  return s;
}
const ParamSpec& gp_mode() {
  static const ParamSpec s = ParamSpec::choice(
      "gp-mode", {"default", "paper"}, "default",
      "default (the covariance and hyper-parameters the flags give; cells farther than --gp-length from every hit "
      "and beam unknown) or paper (IJRR 2012: the neural-network covariance of eq. 7 with S = diag(s0^2, s1^2, ...) "
      "in the world's frame, learned with s2 and sn by CRS2 then L-BFGS on --gp-train-points points of the first "
      "--gp-train-scans scans; 15 + 15 neighbours; every cell of the data's bounding box grown by --gp-length "
      "mapped, those farther than --gp-length from every hit and beam at the GP prior; CPU only; not with "
      "--gp-covariance, --gp-hyperparameters or the expected kernel)");
  return s;
}
const ParamSpec& gp_train_scans() {
  static const ParamSpec s = ParamSpec::whole_number(
      "gp-train-scans", 10, 1, 1e6, "--gp-mode paper: the hyper-parameters are learned on the first this many scans");
  return s;
}
const ParamSpec& gp_train_points() {
  static const ParamSpec s = ParamSpec::whole_number(
      "gp-train-points", 500, 10, 5000,
      "--gp-mode paper: training points drawn from those scans, half hits, half points on beams (the paper's 500)");
  return s;
}
const ParamSpec& gp_hyperparameters() {
  static const ParamSpec s = ParamSpec::choice(
      "gp-hyperparameters", {"given", "learn"}, "given",
      "Given (--gp-length, --gp-signal, --gp-noise) or learn (maximising the marginal likelihood of "
      "sampled local models, from the given values and random restarts; --gp-length still sets the mapped reach)");
  return s;
}
const ParamSpec& gp_range_sigma() {
  static const ParamSpec s =
      ParamSpec::number("gp-range-sigma", 0, at_least(0), at_most(kMaxGpRangeSigmaM),
                        "The sensor's range noise (m); with --gp-bearing-sigma it makes every training input "
                        "uncertain, taken by the expected kernel (GPPOL)")
          .in_unit("m");
  return s;
}
const ParamSpec& gp_bearing_sigma() {
  static const ParamSpec s = ParamSpec::number("gp-bearing-sigma", 0, at_least(0), below(0.5),
                                               "The sensor's bearing noise (rad; azimuth, and elevation in 3-D)")
                                 .in_unit("rad");
  return s;
}
const ParamSpec& gp_input_correlation() {
  static const ParamSpec s = ParamSpec::choice(
      "gp-input-correlation", {"independent", "scan", "trajectory"}, "trajectory",
      "Under --pose-fusion kernel: how the training inputs' pose displacements correlate: "
      "independent (GPPOL as published), scan (a scan's inputs move together) or trajectory (and the scans' "
      "sigma points paired, as the expected sub-map pairs them; their covariances must have one rank)");
  return s;
}

}  // namespace

const std::vector<const ParamSpec*>& gpom_param_specs() {
  static const std::vector<const ParamSpec*> specs = {
      &gp_noise_param(),   &gp_covariance(),  &gp_length(),        &gp_signal(),           &gp_neighbours(),
      &gp_hyperparameters(), &gp_range_sigma(), &gp_bearing_sigma(), &gp_input_correlation()};
  return specs;
}

GpomParams gpom_params(const MethodParams& m) {
  GpomParams p;
  p.gp_noise = m.number("gp-noise");
  p.gp_covariance = m.choice("gp-covariance");
  p.gp_length_m = m.number("gp-length");
  p.gp_signal_var = m.number("gp-signal");
  p.gp_neighbours = m.whole("gp-neighbours");
  p.gp_hyperparameters = m.choice("gp-hyperparameters");
  p.gp_range_sigma = m.number("gp-range-sigma");
  p.gp_bearing_sigma = m.number("gp-bearing-sigma");
  p.gp_input_correlation = m.choice("gp-input-correlation");
  p.wgp_terms = m.whole("wgp-terms");
  p.gp_mode = m.choice("gp-mode");
  p.gp_train_scans = m.whole("gp-train-scans");
  p.gp_train_points = m.whole("gp-train-points");
  return p;
}

const MethodDescriptor& gpom_descriptor() {
  static const MethodDescriptor descriptor = [] {
    MethodDescriptor d;
    d.name = "gpom";
    d.summary = "Gaussian process occupancy map: a GP per query on its nearest hits and beams, PLSC squashing";
    d.params = gpom_param_specs();
    d.params.insert(d.params.begin(), &gp_mode());  // gpom's alone: wgpom has no paper mode
    d.params.push_back(&gp_train_scans());
    d.params.push_back(&gp_train_points());
    d.capabilities.pose_uncertainty = true;
    d.capabilities.devices = {"cpu", "opencl"};
    d.variance = "the variance of the local model's prediction of the latent label; occupancy is its PLSC squashing";
    d.make = [](const BuildParams& p, const MethodParams& m, const BackendOptions& b) {
      return make_gpom_method(p, m, b);
    };
    return d;
  }();
  return descriptor;
}

}  // namespace bgkmap
