// The BVH raycaster returns exactly what testing every primitive returns.
#include <gtest/gtest.h>

#include <random>

#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/raycaster.hpp"
#include "sim/sim_test_util.hpp"

namespace bgkmap::sim {
namespace {

void expect_same_as_brute_force(const Scene& scene, const std::vector<Ray>& rays, double t_max) {
  const Raycaster raycaster(scene);
  size_t hits = 0;
  for (const Ray& ray : rays) {
    const auto fast = raycaster.cast(ray, t_max);
    const auto slow = cast_brute_force(scene, ray, t_max);
    ASSERT_EQ(fast.has_value(), slow.has_value());
    if (!fast) continue;
    ++hits;
    ASSERT_EQ(fast->t, slow->t);
    ASSERT_EQ(fast->primitive, slow->primitive);
  }
  EXPECT_GT(hits, rays.size() / 50);
  EXPECT_LT(hits, rays.size());
}

TEST(Raycaster, EqualsBruteForceOnRandomScenes) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1, 1);
  Scene scene;
  for (int i = 0; i < 80; ++i) {
    scene.primitives.push_back(testing_support::random_box(rng, 20));
    scene.primitives.push_back(testing_support::random_cylinder(rng, 20));
    scene.primitives.push_back(testing_support::random_sphere(rng, 20));
    if (i % 10 == 0) scene.primitives.push_back(testing_support::random_height_field(rng, 20));
  }
  // One plane far below most of it, so that some rays still miss everything.
  scene.primitives.push_back(HalfSpace({0, 0, -30}, {0.1, 0, 1}));
  std::vector<Ray> rays;
  for (int k = 0; k < 20000; ++k) rays.push_back({{22 * u(rng), 22 * u(rng), 22 * u(rng)}, normalized({u(rng), u(rng), u(rng)})});
  // Axis-parallel rays exercise the zero components of the slab tests.
  for (int k = 0; k < 2000; ++k) {
    Vec3d d{0, 0, 0};
    (k % 3 == 0 ? d.x : (k % 3 == 1 ? d.y : d.z)) = (k % 2 ? 1 : -1);
    rays.push_back({{22 * u(rng), 22 * u(rng), 22 * u(rng)}, d});
  }
  expect_same_as_brute_force(scene, rays, 60);
  expect_same_as_brute_force(scene, rays, 5);  // a short max range culls whole subtrees
}

TEST(Raycaster, TiesGoToTheLowerIndex) {
  Scene scene;
  scene.primitives.push_back(Box({5, 0, 0}, {2, 2, 2}));
  scene.primitives.push_back(Box({5, 0, 0}, {2, 1, 1}, {}));  // same front face x = 4 on the ray
  scene.primitives.push_back(Sphere({4.5, 0, 0}, 0.5));       // touches x = 4 too
  const Raycaster raycaster(scene);
  const auto hit = raycaster.cast({{0, 0, 0}, {1, 0, 0}}, 10);
  ASSERT_TRUE(hit);
  EXPECT_EQ(hit->t, 4.0);
  EXPECT_EQ(hit->primitive, 0u);
}

TEST(Raycaster, EqualsBruteForceOnTheCampus) {
  const SimulationSpec campus = make_preset("campus");
  const std::vector<Pose> poses = sample_poses(campus.trajectory);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  std::vector<Ray> rays;
  for (int k = 0; k < 3000; ++k) {
    const Pose& p = poses[rng() % poses.size()];
    rays.push_back({{p.position.x, p.position.y, p.position.z}, normalized({u(rng), u(rng), 0.3 * u(rng)})});
  }
  expect_same_as_brute_force(campus.scene, rays, 100);
}

}  // namespace
}  // namespace bgkmap::sim
