// The warp hook: gpom's GP models the labels y as they are, wgpom's their warp z = g(y) (warped_gp),
// a prediction of z taken back to label space over its Gaussian.
#pragma once

#include <vector>

#include "core/gauss_hermite.hpp"
#include "methods/gp/gp_regression.hpp"
#include "methods/wgpom/warped_gp.hpp"

namespace bgkmap::gpom {

class LabelWarp {
 public:
  // warp null: gpom (no warp).
  LabelWarp(const TanhWarp* warp, const GaussHermite& quadrature) : warp_(warp), quadrature_(&quadrature) {}

  // The labels the GP models: `labels`, or their warp in `buffer`.
  const std::vector<double>& modelled(const std::vector<double>& labels, std::vector<double>& buffer) const {
    if (!warp_) return labels;
    buffer.resize(labels.size());
    for (size_t i = 0; i < labels.size(); ++i) buffer[i] = warp_->value(labels[i]);
    return buffer;
  }

  // A latent prediction of the modelled labels in label space.
  GpPrediction label_space(const GpPrediction& latent) const {
    return warp_ ? unwarp_prediction(latent.mean, latent.variance, *warp_, *quadrature_) : latent;
  }

 private:
  const TanhWarp* warp_;
  const GaussHermite* quadrature_;
};

}  // namespace bgkmap::gpom
