// The `dynamic` preset: a world that changes while it is scanned. Two rooms side by side; the
// robot loops in the west one. The door between them opens at scan 20 (the east room comes into
// view), a car parked along the north wall leaves at scan 15, one person paces along the south
// wall of the west room and another across the east room.
#include "bgkmap/sim/presets.hpp"
#include "sim/box_between.hpp"

namespace bgkmap::sim {

SimulationSpec make_dynamic_preset() {
  SimulationSpec spec;
  spec.name = "dynamic";
  spec.truth_resolution_m = 0.1;
  spec.sensor = sensor_preset("vlp16");
  spec.sensor.name = "vlp16-1deg";
  spec.sensor.azimuth_resolution_deg = 1.0;  // 5760 beams a scan: a quick preset
  spec.scene.bounds = Box3d{{-0.4, -0.4, -0.4}, {10.4, 5.6, 2.4}};
  auto& p = spec.scene.primitives;
  const double wall = 0.2, height = 2.0;
  p.push_back(HalfSpace({0, 0, 0}, {0, 0, 1}));                           // floor
  p.push_back(box_between({0, 0, height}, {10, 5, height + wall}));        // ceiling
  p.push_back(box_between({0, 0, 0}, {10, wall, height}));                 // south wall
  p.push_back(box_between({0, 5 - wall, 0}, {10, 5, height}));             // north wall
  p.push_back(box_between({0, wall, 0}, {wall, 5 - wall, height}));        // west wall
  p.push_back(box_between({10 - wall, wall, 0}, {10, 5 - wall, height}));  // east wall
  p.push_back(box_between({4.9, wall, 0}, {5.1, 2.0, height}));            // west | east, door at y 2..3
  p.push_back(box_between({4.9, 3.0, 0}, {5.1, 5 - wall, height}));
  p.push_back(Box({8.0, 1.0, 0.4}, {1.6, 0.8, 0.8}));                      // east room: crate
  p.push_back(Cylinder({1.0, 4.2, 0}, {1.0, 4.2, 1.2}, 0.2));              // west room: pillar

  auto& d = spec.scene.dynamic;
  DynamicObject door{"door", box_between({4.92, 2.0, 0}, {5.08, 3.0, height}), 0, 20, {}, false, 0};
  DynamicObject car{"car", box_between({1.8, 3.9, 0}, {3.6, 4.7, 1.0}), 0, 15, {}, false, 0};
  DynamicObject walker_west{"walker west", Cylinder({0.8, 0.7, 0}, {0.8, 0.7, 1.7}, 0.25), 0, std::nullopt, {}, false, 0};
  walker_west.path = {{0.8, 0.7, 0}, {4.2, 0.7, 0}};
  walker_west.speed_m_per_scan = 0.2;
  DynamicObject walker_east{"walker east", Cylinder({6.0, 2.5, 0}, {6.0, 2.5, 1.7}, 0.25), 0, std::nullopt, {}, false, 0};
  walker_east.path = {{6.0, 2.5, 0}, {9.2, 2.5, 0}};
  walker_east.speed_m_per_scan = 0.15;
  d = {door, car, walker_west, walker_east};

  // The robot: a VLP-16 at 1 m on a loop between the walker's lane and the car.
  spec.trajectory.scans = 40;
  spec.trajectory.closed = true;
  for (const Vec3d& w : {Vec3d{1.6, 1.7, 1}, Vec3d{3.8, 1.7, 1}, Vec3d{3.8, 3.2, 1}, Vec3d{1.6, 3.2, 1}})
    spec.trajectory.waypoints.push_back({w, std::nullopt});
  return spec;
}

}  // namespace bgkmap::sim
