#include "methods/gp/gp_params.hpp"

namespace bgkmap {

// Labels are +-1: far past this bound the GP's squares and products overflow and nearer, the
// data are already swamped.
constexpr double kMaxGpNoise = 1e3;

const ParamSpec& gp_noise_param() {
  static const ParamSpec spec =
      ParamSpec::number("gp-noise", 0.1, above(0), at_most(kMaxGpNoise),
                        "Observation noise sigma_n (gpoctomap's kernel: --ell, signal variance --sigma0)")
          .with_note("a standard deviation of labels +-1");
  return spec;
}

}  // namespace bgkmap
