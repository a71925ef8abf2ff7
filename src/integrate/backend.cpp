#include "bgkmap/integrate/backend.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/device_engine.hpp"

namespace bgkmap {

namespace {

// The CPU path in place of the device asked for (its BackendInfo::note says why), or that auto
// chose (its BackendInfo::reason says why). The CPU path keeps no cells of its own: nothing to
// forward of the residency.
class Substitute final : public Integrator {
 public:
  Substitute(std::unique_ptr<CpuIntegrator> inner, std::string note, std::string reason)
      : inner_(std::move(inner)), note_(std::move(note)), reason_(std::move(reason)) {}

  BackendInfo info() const override {
    BackendInfo b = inner_->info();
    b.note = note_;
    b.reason = reason_;
    return b;
  }
  void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                 IntegrateStats& stats) override {
    inner_->integrate(obs, buckets, map, stats);
  }
  void prepare(const BgkMap& map) override { inner_->prepare(map); }
  int idle_host_threads() const override { return inner_->idle_host_threads(); }
  void finish(IntegrateStats& stats) override { inner_->finish(stats); }

 private:
  std::unique_ptr<CpuIntegrator> inner_;
  std::string note_, reason_;
};

}  // namespace

BackendInfo backend_info(DeviceKind kind, std::string device, int threads, std::string note, std::string reason) {
  BackendInfo b;
  b.name = device_kind_name(kind);
  b.device = std::move(device);
  b.threads = threads;
  b.note = std::move(note);
  b.reason = std::move(reason);
  b.kind = kind;
  return b;
}

void check_thread_count(int threads) {
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int most = std::max(64, kMaxThreadsPerCore * cores);
  if (threads < 0 || threads > most)
    throw std::invalid_argument("--threads " + std::to_string(threads) + " is outside 0 (all cores) to " +
                                std::to_string(most) + " (" + std::to_string(kMaxThreadsPerCore) + " a core, at least 64)");
}

std::unique_ptr<Integrator> make_integrator(const ComputeDevice& device) {
  return make_engine<Integrator>(
      device,
      [](const ComputeDevice& d) {
        OpenClOptions opencl;
        opencl.device_filter = d.device_filter();
        opencl.kernel_dir = d.kernel_dir();
        return make_opencl_integrator(opencl, d.threads());
      },
      [](const ComputeDevice& d) -> std::unique_ptr<Integrator> {
        auto cpu = std::make_unique<CpuIntegrator>(d.threads());
        if (d.note().empty() && d.reason().empty()) return cpu;
        return std::make_unique<Substitute>(std::move(cpu), d.note(), d.reason());
      });
}

std::unique_ptr<Integrator> make_integrator(const BackendOptions& options) {
  return make_integrator(ComputeDevice::choose(options));
}

}  // namespace bgkmap
