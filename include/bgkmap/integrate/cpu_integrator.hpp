// The OpenMP back end: blocks in parallel, every cell against every bucketed observation.
#pragma once

#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

class CpuIntegrator final : public Integrator {
 public:
  // threads <= 0: OpenMP's default (all cores).
  explicit CpuIntegrator(int threads = 0);

  BackendInfo info() const override;
  void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                 IntegrateStats& stats) override;

 private:
  int threads_;
};

}  // namespace bgkmap
