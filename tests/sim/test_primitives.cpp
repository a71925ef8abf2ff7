// Inside tests and first hits of every primitive: hand-computed cases, then random rays against
// a brute-force march along the ray with the exact inside test.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bgkmap/sim/primitives.hpp"
#include "sim/sim_test_util.hpp"

namespace bgkmap::sim {
namespace {

TEST(Primitives, BoxInsideAxisAlignedAndRotated) {
  const Box box({1, 2, 3}, {2, 4, 6});
  EXPECT_TRUE(box.contains({1, 2, 3}));
  EXPECT_TRUE(box.contains({2, 4, 6}));  // corner: closed solid
  EXPECT_FALSE(box.contains({2.001, 2, 3}));
  EXPECT_FALSE(box.contains({1, 2, -0.001}));

  const Box turned({0, 0, 0}, {4, 2, 2}, {0, 0, 90});  // its long side now runs along y
  EXPECT_TRUE(turned.contains({0, 1.9, 0}));
  EXPECT_FALSE(turned.contains({1.9, 0, 0}));
  EXPECT_TRUE(turned.contains({0.9, 0, 0}));

  const Box diamond({0, 0, 0}, {2, 2, 2}, {0, 0, 45});  // a corner on the x axis at sqrt(2)
  EXPECT_TRUE(diamond.contains({1.41, 0, 0}));
  EXPECT_FALSE(diamond.contains({1.42, 0, 0}));
  EXPECT_FALSE(diamond.contains({0.75, 0.75, 0}));  // the old corner (1, 1) is cut off

  const Box pitched({0, 0, 0}, {2, 2, 2}, {0, 45, 0});  // a corner on the z axis
  EXPECT_TRUE(pitched.contains({0, 0, 1.41}));
  EXPECT_FALSE(pitched.contains({0, 0, 1.42}));
}

TEST(Primitives, CylinderSphereHalfSpaceInside) {
  const Cylinder upright({0, 0, 0}, {0, 0, 2}, 1);
  EXPECT_TRUE(upright.contains({0.7, 0.7, 1}));    // 0.98 from the axis
  EXPECT_FALSE(upright.contains({0.71, 0.71, 1}));  // 1.0041
  EXPECT_TRUE(upright.contains({0, 0, 2}));
  EXPECT_FALSE(upright.contains({0, 0, 2.001}));
  EXPECT_FALSE(upright.contains({0, 0, -0.001}));

  // Axis along (1, 1, 0) / sqrt(2), length 2 sqrt(2); (1, 1, 0.49) is 0.49 from the axis.
  const Cylinder lying({0, 0, 0}, {2, 2, 0}, 0.5);
  EXPECT_TRUE(lying.contains({1, 1, 0.49}));
  EXPECT_FALSE(lying.contains({1, 1, 0.51}));
  EXPECT_TRUE(lying.contains({1.3, 0.7, 0}));   // 0.42 from the axis
  EXPECT_FALSE(lying.contains({1.4, 0.6, 0}));  // 0.566
  EXPECT_FALSE(lying.contains({-0.1, -0.1, 0}));  // behind the base cap

  const Sphere ball({1, 1, 1}, 2);
  EXPECT_TRUE(ball.contains({3, 1, 1}));
  EXPECT_FALSE(ball.contains({3.001, 1, 1}));
  EXPECT_TRUE(ball.contains({2.1, 2.1, 2.1}));   // 1.905 from the centre
  EXPECT_FALSE(ball.contains({2.2, 2.2, 2.2}));  // 2.078

  const HalfSpace ground({0, 0, 0.5}, {0, 0, 7});  // normal is normalized
  EXPECT_DOUBLE_EQ(ground.normal().z, 1.0);
  EXPECT_TRUE(ground.contains({100, -50, 0.5}));
  EXPECT_TRUE(ground.contains({0, 0, -30}));
  EXPECT_FALSE(ground.contains({0, 0, 0.5001}));
}

TEST(Primitives, HeightFieldInsideIsBilinear) {
  // Heights 0, 1 along x and 2, 3 one cell up in y: h(x, y) = x + 2y over [0, 1]^2.
  const HeightField hf(0, 0, 1, -1, {{0, 1}, {2, 3}});
  EXPECT_DOUBLE_EQ(hf.height_at(0.5, 0.5), 1.5);
  EXPECT_DOUBLE_EQ(hf.height_at(0.25, 0.75), 1.75);
  EXPECT_TRUE(hf.contains({0.5, 0.5, 1.49}));
  EXPECT_FALSE(hf.contains({0.5, 0.5, 1.51}));
  EXPECT_FALSE(hf.contains({1.5, 0.5, 0}));       // outside the grid
  EXPECT_FALSE(hf.contains({0.5, 0.5, -1.01}));   // below the base
  EXPECT_TRUE(hf.contains({0.5, 0.5, -1}));
  // A saddle: h = x y on one cell is not a plane.
  const HeightField saddle(0, 0, 1, -1, {{0, 0}, {0, 1}});
  EXPECT_DOUBLE_EQ(saddle.height_at(0.5, 0.5), 0.25);
  EXPECT_DOUBLE_EQ(saddle.height_at(0.2, 0.9), 0.18);
  // Several cells: the right cell is picked.
  const HeightField steps(10, 20, 0.5, 0, {{1, 2, 3}, {1, 2, 3}});
  EXPECT_DOUBLE_EQ(steps.height_at(10.75, 20.25), 2.5);
}

TEST(Primitives, DegenerateShapesAreRejected) {
  EXPECT_THROW(Box({0, 0, 0}, {1, 0, 1}), std::invalid_argument);
  EXPECT_THROW(Cylinder({0, 0, 0}, {0, 0, 0}, 1), std::invalid_argument);
  EXPECT_THROW(Cylinder({0, 0, 0}, {0, 0, 1}, -1), std::invalid_argument);
  EXPECT_THROW(Sphere({0, 0, 0}, 0), std::invalid_argument);
  EXPECT_THROW(HalfSpace({0, 0, 0}, {0, 0, 0}), std::invalid_argument);
  EXPECT_THROW(HeightField(0, 0, 1, 0, {{0, 1}}), std::invalid_argument);
  EXPECT_THROW(HeightField(0, 0, 1, 0.5, {{0, 1}, {1, 1}}), std::invalid_argument);  // base above a height
  EXPECT_THROW(HeightField(0, 0, 1, 0, {{0, 1}, {1}}), std::invalid_argument);
}

TEST(Primitives, FirstHitsByHand) {
  const Ray along_x{{-5, 2, 3}, {1, 0, 0}};
  EXPECT_DOUBLE_EQ(*Box({1, 2, 3}, {2, 4, 6}).first_hit(along_x, 100), 5.0);
  EXPECT_FALSE(Box({1, 2, 3}, {2, 4, 6}).first_hit(along_x, 4.9));  // beyond t_max

  const Ray x_axis{{-5, 0, 0}, {1, 0, 0}};
  EXPECT_NEAR(*Box({0, 0, 0}, {2, 2, 2}, {0, 0, 45}).first_hit(x_axis, 100), 5 - std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(*Sphere({0, 0, 0}, 2).first_hit({{-5, 1, 0}, {1, 0, 0}}, 100), 5 - std::sqrt(3.0), 1e-12);

  const Cylinder upright({0, 0, 0}, {0, 0, 2}, 1);
  EXPECT_NEAR(*upright.first_hit({{-5, 0.6, 1}, {1, 0, 0}}, 100), 4.2, 1e-12);
  EXPECT_NEAR(*upright.first_hit({{0.5, 0, 5}, {0, 0, -1}}, 100), 3.0, 1e-12);  // through the top cap
  EXPECT_FALSE(upright.first_hit({{1.5, 0, 5}, {0, 0, -1}}, 100));
  EXPECT_FALSE(upright.first_hit({{-5, 0.6, 2.5}, {1, 0, 0}}, 100));  // above it

  const double s = std::sqrt(0.5);
  EXPECT_NEAR(*HalfSpace({0, 0, 0}, {0, 0, 1}).first_hit({{0, 0, 2}, {s, 0, -s}}, 100), 2 * std::sqrt(2.0), 1e-12);
  EXPECT_FALSE(HalfSpace({0, 0, 0}, {0, 0, 1}).first_hit({{0, 0, 2}, {s, 0, s}}, 100));

  // Rays that start inside hit at 0; rays pointing away miss.
  EXPECT_EQ(*Sphere({0, 0, 0}, 2).first_hit({{0.5, 0, 0}, {1, 0, 0}}, 100), 0.0);
  EXPECT_EQ(*HalfSpace({0, 0, 0}, {0, 0, 1}).first_hit({{0, 0, -1}, {0, 0, 1}}, 100), 0.0);
  EXPECT_FALSE(Sphere({0, 0, 0}, 2).first_hit({{5, 0, 0}, {1, 0, 0}}, 100));

  // Height field h = x + 2y: from above onto (0.5, 0.5, 1.5); sideways at z = 0.5 and y = 0.1,
  // the surface h = x + 0.2 rises through z = 0.5 at x = 0.3.
  const HeightField plane_field(0, 0, 1, -1, {{0, 1}, {2, 3}});
  EXPECT_NEAR(*plane_field.first_hit({{0.5, 0.5, 10}, {0, 0, -1}}, 100), 8.5, 1e-12);
  EXPECT_NEAR(*plane_field.first_hit({{-1, 0.1, 0.5}, {1, 0, 0}}, 100), 1.3, 1e-12);
  // Entering through a side wall below the surface: hit on the wall.
  EXPECT_NEAR(*plane_field.first_hit({{-1, 0.5, 0.5}, {1, 0, 0}}, 100), 1.0, 1e-12);
  EXPECT_FALSE(plane_field.first_hit({{-1, 0.5, 3.5}, {1, 0, 0}}, 100));
  // Saddle h = x y along the diagonal x = y = u: h = u^2, crossing z = 0.25 at u = 0.5.
  const HeightField saddle(0, 0, 1, -1, {{0, 0}, {0, 1}});
  EXPECT_NEAR(*saddle.first_hit({{0, 0, 0.25}, {s, s, 0}}, 100), 0.5 * std::sqrt(2.0), 1e-12);
}

// The reference: step along the ray with the exact inside test.
void expect_matches_march(const Primitive& primitive, const Ray& ray, double t_max, const std::string& what) {
  const std::optional<double> hit = first_hit(primitive, ray, t_max);
  const double step = 2e-3;
  const double last_outside = hit ? *hit - 1e-9 : t_max;
  for (double t = 0; t <= last_outside; t += step)
    ASSERT_FALSE(contains(primitive, ray.at(t))) << what << ": inside at t = " << t << " before the hit "
                                                 << (hit ? std::to_string(*hit) : "none");
  if (!hit) return;
  ASSERT_LE(*hit, t_max);
  // An inside point right at (or just after) the reported hit: it is a real entry.
  bool inside_near = false;
  for (int k = 0; k <= 2000 && !inside_near; ++k) inside_near = contains(primitive, ray.at(*hit + k * 5e-8));
  EXPECT_TRUE(inside_near) << what << ": nothing inside just after t = " << *hit;
}

TEST(Primitives, FirstHitsMatchMarchingOnRandomRays) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  int hits = 0, rays = 0;
  for (int shape = 0; shape < 60; ++shape) {
    for (const Primitive& p : testing_support::random_primitives(rng, 1)) {
      for (int r = 0; r < 40; ++r) {
        const Ray ray{{4 * u(rng), 4 * u(rng), 4 * u(rng)}, normalized({u(rng), u(rng), u(rng)})};
        expect_matches_march(p, ray, 10.0, type_name(p));
        hits += first_hit(p, ray, 10.0).has_value();
        ++rays;
      }
    }
  }
  // The rays must exercise both outcomes.
  EXPECT_GT(hits, rays / 10);
  EXPECT_LT(hits, rays * 9 / 10);
}

TEST(Primitives, BoundsContainTheSolid) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-5, 5);
  for (const Primitive& p : testing_support::random_primitives(rng, 40)) {
    const auto box = bounds(p);
    if (!box) continue;
    for (int k = 0; k < 4000; ++k) {
      const Vec3d q{u(rng), u(rng), u(rng)};
      if (contains(p, q)) {
        ASSERT_TRUE(box->contains(q)) << type_name(p);
      }
    }
  }
}

TEST(Primitives, RelationIsConservative) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u(-4, 4), len(0.01, 2);
  int decided = 0;
  for (const Primitive& p : testing_support::random_primitives(rng, 20)) {
    for (int k = 0; k < 200; ++k) {
      const Vec3d lo{u(rng), u(rng), u(rng)};
      const Box3d box{lo, lo + Vec3d{len(rng), len(rng), len(rng)}};
      const BoxRelation r = relation(p, box);
      if (r == BoxRelation::kMixed) continue;
      ++decided;
      std::uniform_real_distribution<double> fx(box.min.x, box.max.x), fy(box.min.y, box.max.y), fz(box.min.z, box.max.z);
      for (int s = 0; s < 200; ++s) {
        const Vec3d q = s < 8 ? box.corner(s) : Vec3d{fx(rng), fy(rng), fz(rng)};
        ASSERT_EQ(contains(p, q), r == BoxRelation::kInside) << type_name(p);
      }
    }
  }
  EXPECT_GT(decided, 1000);
}

}  // namespace
}  // namespace bgkmap::sim
