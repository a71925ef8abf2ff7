#include "bgkmap/integrate/backend.hpp"

#include <algorithm>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/opencl/opencl_runtime.hpp"

namespace bgkmap {

namespace {

// A back end that runs in place of the one asked for (its BackendInfo::note says why), or that
// auto chose (its BackendInfo::reason says why).
class Substitute final : public Integrator {
 public:
  Substitute(std::unique_ptr<Integrator> inner, std::string note, std::string reason = "")
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
  void synchronize(BgkMap& map) override { inner_->synchronize(map); }
  void synchronize_slots(BgkMap& map, const std::vector<uint32_t>& slots) override {
    inner_->synchronize_slots(map, slots);
  }
  void host_map_changed() override { inner_->host_map_changed(); }
  void host_slots_changed(const std::vector<uint32_t>& slots) override { inner_->host_slots_changed(slots); }

 private:
  std::unique_ptr<Integrator> inner_;
  std::string note_, reason_;
};


}  // namespace

void check_thread_count(int threads) {
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  const int most = std::max(64, kMaxThreadsPerCore * cores);
  if (threads < 0 || threads > most)
    throw std::invalid_argument("--threads " + std::to_string(threads) + " is outside 0 (all cores) to " +
                                std::to_string(most) + " (" + std::to_string(kMaxThreadsPerCore) + " a core, at least 64)");
}

std::string opencl_device_filter(const BackendOptions& options) {
  if (!options.device_filter.empty()) return options.device_filter;
  const char* env = std::getenv("BGKMAP_OPENCL_DEVICE");
  return env ? env : "";
}

std::unique_ptr<Integrator> make_integrator(const BackendOptions& options) {
  check_thread_count(options.threads);
  if (options.backend == "cpu") return std::make_unique<CpuIntegrator>(options.threads);
  if (options.backend != "auto" && options.backend != "opencl")
    throw std::invalid_argument("unknown backend '" + options.backend + "' (expected auto, cpu or opencl)");

  OpenClOptions opencl;
  opencl.device_filter = opencl_device_filter(options);
  try {
    if (options.backend == "auto") {
      // On the same CPU the OpenMP path beats an OpenCL CPU driver (PoCL): auto takes only a GPU.
      const OpenClDeviceInfo device = opencl_detail::selected_device(opencl.device_filter);
      if (device.type != "GPU")
        return std::make_unique<Substitute>(std::make_unique<CpuIntegrator>(options.threads), "",
                                            "the OpenCL device '" + device.full_name() +
                                                "' is not a GPU, and the CPU path is faster on the same CPU "
                                                "(--backend opencl uses it)");
    }
    return make_opencl_integrator(opencl, options.threads);
  } catch (const OpenClUnavailable& e) {
    // The same map on the CPU path; the caller says why once.
    return std::make_unique<Substitute>(
        std::make_unique<CpuIntegrator>(options.threads),
        std::string(options.backend == "auto" ? "no usable OpenCL device" : "OpenCL unavailable") +
            ", using the CPU path: " + e.what());
  }
}

}  // namespace bgkmap
