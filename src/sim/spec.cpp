#include "bgkmap/sim/spec.hpp"

#include <cmath>
#include <stdexcept>

#include "bgkmap/sim/truth.hpp"

namespace bgkmap::sim {

void SimulationSpec::validate() const {
  sensor.validate();
  trajectory.validate();
  if (scene.primitives.empty()) throw std::invalid_argument("the scene has no primitives");
  if (!(truth_resolution_m >= 0) || !std::isfinite(truth_resolution_m))
    throw std::invalid_argument("truth_resolution must be >= 0 (0: no truth map)");
  for (const DynamicObject& object : scene.dynamic) object.validate();
  if (!scene.dynamic.empty() && !scene.bounds)
    throw std::invalid_argument("a scene with dynamic objects needs bounds: {min: [x, y, z], max: [x, y, z]}");
  const Box3d region = truth_region(scene);  // throws when a plane leaves the truth unbounded
  if (truth_resolution_m > 0) check_truth_region(region, truth_resolution_m);
}

}  // namespace bgkmap::sim
