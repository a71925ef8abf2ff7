#include "methods/gpom/calibration.hpp"

namespace bgkmap::gpom {

void PlscCalibration::refit(const std::vector<std::vector<LooSample>>& loo, int threads) {
  for (const std::vector<LooSample>& samples : loo) pool_.insert(pool_.end(), samples.begin(), samples.end());
  while (pool_.size() > kMaxLooSamples) {
    size_t kept = 0;
    for (size_t i = 0; i < pool_.size(); i += 2) pool_[kept++] = pool_[i];
    pool_.resize(kept);
  }
  plsc_ = fit_plsc(pool_, plsc_, threads);
}

}  // namespace bgkmap::gpom
