// The back-end interface: add one scan's kernel-weighted counts to the cells of its blocks.
// The CPU (OpenMP) and OpenCL back ends implement it; bucketing is shared host code.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct IntegrateStats {
  uint64_t pairs_evaluated = 0;       // (cell, observation) pairs whose distance was computed
  uint64_t pairs_within_support = 0;  // of those, pairs closer than the support radius
};

struct BackendInfo {
  std::string name;    // "cpu" or "opencl"
  std::string device;  // human-readable device name
  int threads = 1;     // host threads the back end uses
  std::string note;    // why this back end runs (e.g. the fallback reason), empty if chosen directly
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual BackendInfo info() const = 0;

  // Adds the observations' kernel-weighted counts to every cell of every block in `buckets`.
  // Every BlockWork's slot must already exist in `map`.
  virtual void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                         IntegrateStats& stats) = 0;

  // Makes the map's host cells current. Back ends that keep the map elsewhere copy it back here.
  virtual void synchronize(BgkMap& map) { (void)map; }
};

}  // namespace bgkmap
