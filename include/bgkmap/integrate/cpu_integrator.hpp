// The OpenMP back end: blocks in parallel, every cell against every bucketed observation.
#pragma once

#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

class CpuIntegrator final : public Integrator {
 public:
  // threads <= 0: OpenMP's default (all cores). Where the CPU has AVX-512 (x86-64-v4), the beams
  // of 8^3 blocks run in a loop written for it unless `avx512_beams` is false; the portable loops
  // give the same sums, bit for bit (a test compares them).
  explicit CpuIntegrator(int threads = 0, bool avx512_beams = true);

  BackendInfo info() const override;
  void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                 IntegrateStats& stats) override;

 private:
  int threads_;
  bool avx512_beams_;
};

}  // namespace bgkmap
