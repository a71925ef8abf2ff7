// BGKOctoMap (T-RO 2019 baseline; internal header, see bgk_method.cpp).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// Free points sampled along a free segment: origin + k * spacing along it, k = 1, 2, ... while
// within its length (the origin itself is not a sample). Exposed for tests.
void sample_free_points(const Vec3f& origin, const Vec3f& free_end, double spacing_m, std::vector<Vec3f>& out);

// Before the free points of `beams` are sampled every `spacing_m`: MemoryLimitExceeded naming
// `method`, the scan and the flags unless `bytes_per_sample` each (at least the point itself)
// fits --max-memory (--free-resolution 1e-6 grew past 2.6 GB under --max-memory 1G).
void require_free_sample_memory(const ScanObservations& beams, double spacing_m, double bytes_per_sample,
                                const std::string& method, uint64_t scan);

// free-resolution: the spacing (m) of the free points sampled along each beam; bgk declares it,
// gpoctomap and bhm read it too (bgk_descriptor.cpp).
const ParamSpec& free_resolution_param();

std::unique_ptr<MappingMethod> make_bgk_method(const BuildParams& params, const MethodParams& method_params,
                                               std::unique_ptr<Integrator> integrator);

}  // namespace bgkmap
