// The back-end interface: add one scan's kernel-weighted counts to the cells of its blocks.
// The CPU (OpenMP) and OpenCL back ends implement it; bucketing is shared host code.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/integrate/bucketing.hpp"
#include "bgkmap/integrate/compute_device.hpp"
#include "bgkmap/integrate/host_cells.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

struct IntegrateStats {
  uint64_t pairs_evaluated = 0;       // (cell, observation) pairs whose distance was computed
  uint64_t pairs_within_support = 0;  // of those, pairs closer than the support radius
  double device_kernel_s = 0;         // OpenCL: the kernels' time on the device (event profiling)
};

struct BackendInfo {
  std::string name;    // "cpu" or "opencl": device_kind_name(kind)
  std::string device;  // human-readable device name
  int threads = 1;     // host threads the back end uses
  std::string note;    // why this back end runs in place of the one asked for (a warning), else empty
  std::string reason{};  // why `auto` chose it (not a problem: no warning), else empty
  DeviceKind kind = DeviceKind::kCpu;  // where the work runs now: what callers test (a fallback makes it kCpu)
};

// How an engine on `kind` describes itself: name from kind.
BackendInfo backend_info(DeviceKind kind, std::string device, int threads, std::string note = "", std::string reason = "");

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
  // The host's cells of those blocks are behind until a HostCells view copies them back.
  virtual void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                         IntegrateStats& stats) = 0;

  // Forgetting: decays the cells of `slots` toward the prior, slot i by factors[i] (decay_cells,
  // map/forgetting.hpp), after every integrate() so far and before the next. By default on the
  // host through a view of those slots; a back end that keeps the map elsewhere may decay its
  // own copy with the same arithmetic (core/bgk_math.h's bgk_decayed).
  virtual void decay_blocks(BgkMap& map, const std::vector<uint32_t>& slots, const std::vector<float>& factors,
                            IntegrateStats& stats);

  // Host threads the caller may use for its own work while the back end has nothing queued (after
  // finish()): a device back end that leaves cores to the device while it works has them then.
  virtual int idle_host_threads() const { return info().threads; }

  // Waits until every integrate() so far is done and adds the statistics still pending.
  virtual void finish(IntegrateStats& stats) { (void)stats; }

  // The host's view of every cell of `map`: every integrate() so far is finished (its statistics
  // added to `stats`) and, unless `access` is kOverwrite, the host's cells are current. A new map,
  // or one the caller replaced, is announced with a kOverwrite view before its first integrate().
  HostCells host_cells(BgkMap& map, IntegrateStats& stats, HostAccess access = HostAccess::kRead);
  // The same for the cells of `slots` only (they must outlive the view); the host's other cells
  // may stay behind the back end's.
  HostCells host_cells(BgkMap& map, const std::vector<uint32_t>& slots, IntegrateStats& stats, HostAccess access);

 private:
  friend class HostCells;
  // Residency, called by HostCells alone, in its order; slots null: every slot. A back end that
  // keeps the map elsewhere copies the cells of `slots` back to the host here.
  virtual void copy_to_host(BgkMap& map, const std::vector<uint32_t>* slots) {
    (void)map;
    (void)slots;
  }
  // The host changed the cells of `slots`: a back end that keeps its own copy takes them before
  // it next integrates or copies cells back.
  virtual void host_changed(const std::vector<uint32_t>* slots) { (void)slots; }
};

}  // namespace bgkmap
