// Preset lookup and the `structured` preset: three rooms joined by doors, furnished with boxes
// (some rotated), cylinders and a ball, under a ceiling so that every beam returns indoors.
#include "bgkmap/sim/presets.hpp"

#include <cmath>
#include <stdexcept>

#include "sim/box_between.hpp"

namespace bgkmap::sim {

const std::vector<std::string>& preset_names() {
  static const std::vector<std::string> names{"structured", "unstructured", "campus", "dynamic"};
  return names;
}

bool is_preset(const std::string& name) {
  for (const auto& n : preset_names())
    if (n == name) return true;
  return false;
}

SimulationSpec make_preset(const std::string& name) {
  if (name == "structured") return make_structured_preset();
  if (name == "unstructured") return make_unstructured_preset();
  if (name == "campus") return make_campus_preset();
  if (name == "dynamic") return make_dynamic_preset();
  std::string list;
  for (const auto& n : preset_names()) list += (list.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown preset '" + name + "' (expected " + list + ", or a scene .yaml file)");
}

SimulationSpec make_structured_preset() {
  SimulationSpec spec;
  spec.name = "structured";
  spec.truth_resolution_m = 0.1;
  spec.sensor = sensor_preset("vlp16");
  // Bounds on multiples of 0.4 m keep the truth octree's cubes large along the edges.
  spec.scene.bounds = Box3d{{-0.4, -0.4, -0.4}, {10.4, 7.2, 2.4}};
  auto& p = spec.scene.primitives;
  const double wall = 0.2, height = 2.0;
  p.push_back(HalfSpace({0, 0, 0}, {0, 0, 1}));                               // floor
  p.push_back(box_between({0, 0, height}, {10, 7, height + wall}));            // ceiling
  p.push_back(box_between({0, 0, 0}, {10, wall, height}));                     // south wall
  p.push_back(box_between({0, 7 - wall, 0}, {10, 7, height}));                 // north wall
  p.push_back(box_between({0, wall, 0}, {wall, 7 - wall, height}));            // west wall
  p.push_back(box_between({10 - wall, wall, 0}, {10, 7 - wall, height}));      // east wall
  p.push_back(box_between({3.9, wall, 0}, {4.1, 2.8, height}));                // room A | B, C: door at y 2.8..3.8
  p.push_back(box_between({3.9, 3.8, 0}, {4.1, 7 - wall, height}));
  p.push_back(box_between({4.1, 3.9, 0}, {6.5, 4.1, height}));                 // room B | C: door at x 6.5..7.5
  p.push_back(box_between({7.5, 3.9, 0}, {10 - wall, 4.1, height}));
  // Room A (west)
  p.push_back(Box({1.5, 5.5, 0.375}, {1.2, 0.8, 0.75}));                     // table
  p.push_back(Box({2.8, 1.2, 0.6}, {0.5, 1.0, 1.2}, {0, 0, 30}));            // cabinet, turned
  p.push_back(Cylinder({0.8, 1.0, 0}, {0.8, 1.0, 0.9}, 0.25));               // bin
  // Room B (south-east)
  p.push_back(Box({6.0, 1.5, 0.4}, {0.8, 0.8, 0.8}));                        // crate
  p.push_back(Box({6.05, 1.5, 1.0}, {0.6, 0.6, 0.4}, {0, 0, 20}));           // crate on top, turned
  p.push_back(Box({8.5, 1.0, 0.4}, {2.0, 0.8, 0.8}));                        // sofa
  p.push_back(Sphere({8.2, 3.0, 0.3}, 0.3));                                 // ball
  p.push_back(Box({4.9, 1.0, 0.5}, {0.6, 0.6, 1.0}, {0, 10, 45}));           // tilted box
  // Room C (north-east)
  p.push_back(Box({9.4, 5.5, 0.9}, {0.4, 2.0, 1.8}));                        // shelf
  p.push_back(Box({5.8, 5.6, 0.375}, {1.4, 0.9, 0.75}, {0, 0, 15}));         // table, turned
  p.push_back(Cylinder({5.0, 6.2, 0}, {5.0, 6.2, height}, 0.2));             // column
  p.push_back(Cylinder({8.0, 6.3, 0.5}, {8.6, 6.3, 0.5}, 0.15));             // pipe lying on supports
  p.push_back(Box({8.3, 6.3, 0.175}, {0.2, 0.3, 0.35}));
  // A robot-mounted VLP-16 at 1 m, from room A through both doors into room C.
  spec.trajectory.scans = 12;
  for (const Vec3d& w : {Vec3d{1.5, 3.3, 1}, Vec3d{4.0, 3.3, 1}, Vec3d{5.5, 2.5, 1}, Vec3d{7.0, 2.2, 1},
                         Vec3d{7.0, 4.0, 1}, Vec3d{7.0, 5.2, 1}, Vec3d{8.5, 5.2, 1}})
    spec.trajectory.waypoints.push_back({w, std::nullopt});
  return spec;
}

}  // namespace bgkmap::sim
