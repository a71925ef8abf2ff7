#include "bgkmap/sim/scene.hpp"

#include <stdexcept>

namespace bgkmap::sim {

bool Scene::contains(const Vec3d& p) const {
  for (const Primitive& primitive : primitives)
    if (sim::contains(primitive, p)) return true;
  return false;
}

Scene scene_at(const Scene& scene, int scan) {
  Scene now{scene.primitives, scene.bounds, {}};
  for (const DynamicObject& object : scene.dynamic)
    if (object.present_at(scan)) now.primitives.push_back(object.shape_at(scan));
  return now;
}

Box3d truth_region(const Scene& scene) {
  if (scene.bounds) return *scene.bounds;
  Box3d region = Box3d::empty();
  bool any = false;
  for (const Primitive& primitive : scene.primitives) {
    const auto box = sim::bounds(primitive);
    if (!box) throw std::invalid_argument(std::string("the scene has a ") + type_name(primitive) +
                                          " (unbounded) but no bounds: add bounds: {min: [x, y, z], max: [x, y, z]}");
    region.expand(*box);
    any = true;
  }
  if (!any) throw std::invalid_argument("the scene has no primitives");
  return region;
}

}  // namespace bgkmap::sim
