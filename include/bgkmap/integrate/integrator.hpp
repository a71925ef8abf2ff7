// The back-end interface: add one scan's kernel-weighted counts to the cells of its blocks.
// The CPU (OpenMP) and OpenCL back ends implement it; bucketing is shared host code.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct IntegrateStats {
  uint64_t pairs_evaluated = 0;       // (cell, observation) pairs whose distance was computed
  uint64_t pairs_within_support = 0;  // of those, pairs closer than the support radius
  double device_kernel_s = 0;         // OpenCL: the kernels' time on the device (event profiling)
};

struct BackendInfo {
  std::string name;    // "cpu" or "opencl"
  std::string device;  // human-readable device name
  int threads = 1;     // host threads the back end uses
  std::string note;    // why this back end runs in place of the one asked for (a warning), else empty
  std::string reason{};  // why `auto` chose it (not a problem: no warning), else empty
};

class Integrator {
 public:
  virtual ~Integrator() = default;
  virtual BackendInfo info() const = 0;

  // Called with the map before its first integrate() (the Mapper does it on construction): a
  // back end may compile or allocate for the map's geometry here rather than in the first scan.
  virtual void prepare(const BgkMap& map) { (void)map; }

  // Adds the observations' kernel-weighted counts to every cell of every block in `buckets`.
  // Every BlockWork's slot must already exist in `map`. An asynchronous back end may return
  // before the work is done (having copied what it needs, so the caller may reuse `obs` and
  // `buckets` at once); statistics of work still running are added by a later call or finish().
  virtual void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                         IntegrateStats& stats) = 0;

  // Host threads the caller may use for its own work while the back end has nothing queued (after
  // finish()): a device back end that leaves cores to the device while it works has them then.
  virtual int idle_host_threads() const { return info().threads; }

  // Waits until every integrate() so far is done and adds the statistics still pending.
  virtual void finish(IntegrateStats& stats) { (void)stats; }

  // Makes the map's host cells current. Back ends that keep the map elsewhere copy it back here.
  virtual void synchronize(BgkMap& map) { (void)map; }

  // Makes the host cells of `slots` current; the others may stay behind the back end's copy.
  // Back ends that keep the map elsewhere copy just those back.
  virtual void synchronize_slots(BgkMap& map, const std::vector<uint32_t>& slots) {
    (void)slots;
    synchronize(map);
  }

  // The caller may change the map's host cells before the next integrate(), or pass another
  // map: a back end that keeps its own copy of the map must take the host's cells again then.
  virtual void host_map_changed() {}

  // The caller changed the host cells of `slots` only (slots it added since start at the prior):
  // a back end that keeps its own copy takes just those, before it next integrates or copies
  // cells back. The host's other cells may be behind that copy.
  virtual void host_slots_changed(const std::vector<uint32_t>& slots) {
    (void)slots;
    host_map_changed();
  }
};

}  // namespace bgkmap
