// The `unstructured` preset: a forest patch the size of the structured rooms. Rolling ground (a
// height field), leaning trunks (cylinders), canopies, bushes and half-buried rocks (spheres);
// open to the sky, so upper beams come back as no-returns.
#include <cmath>
#include <vector>

#include "bgkmap/sim/presets.hpp"
#include "preset_random.hpp"

namespace bgkmap::sim {

namespace {
constexpr double kCell = 0.5;
constexpr double kX0 = -0.5, kY0 = -0.5;
constexpr int kNx = 23, kNy = 17;  // 11 x 8 m of ground

double terrain(double x, double y) {
  return 0.15 * std::sin(0.6 * x) * std::cos(0.8 * y) + 0.08 * std::sin(1.3 * x + 0.7 * y) + 0.05 * y / 7.0;
}

// Distance from p to the polyline (x/y only).
double distance_to_path(double x, double y, const std::vector<Vec3d>& path) {
  double best = 1e300;
  for (size_t i = 0; i + 1 < path.size(); ++i) {
    const double ax = path[i].x, ay = path[i].y, bx = path[i + 1].x, by = path[i + 1].y;
    const double dx = bx - ax, dy = by - ay;
    const double f = std::fmax(0, std::fmin(1, ((x - ax) * dx + (y - ay) * dy) / (dx * dx + dy * dy)));
    best = std::fmin(best, std::hypot(x - ax - f * dx, y - ay - f * dy));
  }
  return best;
}
}  // namespace

SimulationSpec make_unstructured_preset() {
  SimulationSpec spec;
  spec.name = "unstructured";
  spec.truth_resolution_m = 0.1;
  spec.sensor = sensor_preset("vlp16");
  spec.scene.bounds = Box3d{{-0.4, -0.4, -0.4}, {10.4, 7.2, 3.2}};
  auto& p = spec.scene.primitives;

  std::vector<std::vector<double>> heights(kNy, std::vector<double>(kNx));
  for (int j = 0; j < kNy; ++j)
    for (int i = 0; i < kNx; ++i) heights[j][i] = terrain(kX0 + i * kCell, kY0 + j * kCell);
  const HeightField ground(kX0, kY0, kCell, -0.5, heights);
  p.push_back(ground);

  // A winding path; trees keep clear of it so the sensor (0.8 m above ground) never sits in one.
  std::vector<Vec3d> path{{0.8, 1.0, 0}, {3.0, 2.2, 0}, {4.5, 4.8, 0}, {6.5, 5.6, 0}, {8.0, 3.5, 0}, {9.2, 1.2, 0}};
  for (Vec3d& w : path) w.z = ground.height_at(w.x, w.y) + 0.8;

  PresetRandom rng(20240601);
  std::vector<Vec3d> trunks;  // base centres, for spacing
  for (int tries = 0; trunks.size() < 32 && tries < 5000; ++tries) {
    const double x = rng.uniform(0.3, 9.7), y = rng.uniform(0.3, 6.7);
    if (distance_to_path(x, y, path) < 0.9) continue;
    bool crowded = false;
    for (const Vec3d& t : trunks) crowded = crowded || std::hypot(t.x - x, t.y - y) < 0.9;
    if (crowded) continue;
    const double ground_z = ground.height_at(x, y);
    const double radius = rng.uniform(0.06, 0.18), height = rng.uniform(1.3, 2.2);
    const double lean_x = rng.uniform(-0.15, 0.15), lean_y = rng.uniform(-0.15, 0.15);
    const Vec3d base{x, y, ground_z - 0.1}, top{x + lean_x, y + lean_y, ground_z + height};
    p.push_back(Cylinder(base, top, radius));
    if (rng.chance(0.6)) p.push_back(Sphere({top.x, top.y, top.z + 0.1}, rng.uniform(0.35, 0.6)));  // canopy
    trunks.push_back(base);
  }
  for (int placed = 0, tries = 0; placed < 14 && tries < 5000; ++tries) {  // bushes and rocks
    const double x = rng.uniform(0.3, 9.7), y = rng.uniform(0.3, 6.7);
    const bool rock = rng.chance(0.4);
    const double radius = rock ? rng.uniform(0.15, 0.35) : rng.uniform(0.25, 0.45);
    if (distance_to_path(x, y, path) < radius + 0.6) continue;
    const double sink = rock ? 0.4 * radius : -0.6 * radius;  // rocks half buried, bushes raised
    p.push_back(Sphere({x, y, ground.height_at(x, y) - sink}, radius));
    ++placed;
  }

  spec.trajectory.scans = 12;
  for (const Vec3d& w : path) spec.trajectory.waypoints.push_back({w, std::nullopt});
  return spec;
}

}  // namespace bgkmap::sim
