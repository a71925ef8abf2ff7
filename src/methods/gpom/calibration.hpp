// gpom's calibration: a cell's occupancy is the PLSC squashing of its mean and variance (plsc),
// alpha and beta fitted to leave-one-out predictions of a sample of the local models.
#pragma once

#include <cstddef>
#include <vector>

#include "methods/gp/plsc.hpp"

namespace bgkmap::gpom {

// Every this many evaluated cells of a block (its first included) also give their local model's
// leave-one-out predictions to the PLSC fit.
constexpr int kLooEvery = 64;

class PlscCalibration {
 public:
  // One evaluation's samples (per block) join the pool, thinned by half while it holds over
  // kMaxLooSamples; alpha and beta are refitted from the last ones.
  void refit(const std::vector<std::vector<LooSample>>& loo, int threads);

  double probability(double mean, double variance) const { return plsc_probability(mean, variance, plsc_); }

 private:
  static constexpr size_t kMaxLooSamples = 100000;
  std::vector<LooSample> pool_;
  PlscParams plsc_;
};

}  // namespace bgkmap::gpom
