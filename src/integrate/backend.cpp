#include "bgkmap/integrate/backend.hpp"

#include <stdexcept>

#include "bgkmap/integrate/cpu_integrator.hpp"

namespace bgkmap {

std::unique_ptr<Integrator> make_integrator(const BackendOptions& options) {
  if (options.backend == "cpu" || options.backend == "auto") return std::make_unique<CpuIntegrator>(options.threads);
  if (options.backend == "opencl")
    throw std::invalid_argument("backend 'opencl' is not built yet (expected auto or cpu)");
  throw std::invalid_argument("unknown backend '" + options.backend + "' (expected auto, cpu or opencl)");
}

}  // namespace bgkmap
