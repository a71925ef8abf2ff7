// The shared BGK math: sparse kernel, point-segment distance, box kernel, Beta moments.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/bgk_math.h"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {
namespace {

constexpr float kEll = 0.2f, kSigma0 = 0.1f;

TEST(SparseKernel, ValueAtZeroIsSigma0) { EXPECT_FLOAT_EQ(bgk_sparse_kernel(0.0f, kEll, kSigma0), kSigma0); }

TEST(SparseKernel, ZeroAtAndBeyondEll) {
  EXPECT_EQ(bgk_sparse_kernel(kEll, kEll, kSigma0), 0.0f);
  EXPECT_EQ(bgk_sparse_kernel(1.5f * kEll, kEll, kSigma0), 0.0f);
}

TEST(SparseKernel, ContinuousAtEll) {
  // Value and slope vanish as d -> ell from below.
  const float d = kEll * (1.0f - 1e-3f);
  EXPECT_LT(bgk_sparse_kernel(d, kEll, kSigma0), 1e-7f);
}

TEST(SparseKernel, MonotoneDecreasing) {
  float previous = bgk_sparse_kernel(0.0f, kEll, kSigma0);
  for (int i = 1; i <= 1000; ++i) {
    const float k = bgk_sparse_kernel(kEll * i / 1000.0f, kEll, kSigma0);
    EXPECT_LE(k, previous) << "at d = " << kEll * i / 1000.0f;
    previous = k;
  }
}

TEST(SparseKernel, MatchesTheFormulaInDouble) {
  const double pi = 3.14159265358979323846;
  for (double d : {0.01, 0.05, 0.1, 0.15, 0.199}) {
    const double r = d / kEll;
    const double expected = kSigma0 * ((2 + std::cos(2 * pi * r)) / 3 * (1 - r) + std::sin(2 * pi * r) / (2 * pi));
    EXPECT_NEAR(bgk_sparse_kernel(float(d), kEll, kSigma0), expected, 1e-6 * kSigma0) << d;
  }
  // Half way the bracket is (2 + cos(pi)) / 3 * 0.5 + 0 = 1/6.
  EXPECT_NEAR(bgk_sparse_kernel(0.1f, kEll, kSigma0), kSigma0 / 6.0, 1e-7);
}

TEST(SparseKernel, RelativeAccuracyOverTheWholeSupport) {
  // The float evaluation (series near l, reduced sin/cos elsewhere) against the formula in
  // double: within 1e-6 relative, or 1e-9 sigma0 absolute where k itself is that small near l
  // (there d/l rounded to float already moves k by more; 1e-10 is 1e-7 of the prior).
  const double pi = 3.14159265358979323846;
  double worst = 0;
  for (int i = 0; i < 100000; ++i) {
    const double d = kEll * (i + 0.5) / 100000.0;
    const double r = static_cast<double>(static_cast<float>(d)) / kEll;
    const double expected = kSigma0 * ((2 + std::cos(2 * pi * r)) / 3 * (1 - r) + std::sin(2 * pi * r) / (2 * pi));
    const double got = bgk_sparse_kernel(static_cast<float>(d), kEll, kSigma0);
    worst = std::max(worst, std::abs(got - expected) / (1e-6 * expected + 1e-9 * kSigma0));
  }
  EXPECT_LT(worst, 1.0);
}

TEST(PointSegmentDistance, ProjectionInsideTheSegment) {
  EXPECT_FLOAT_EQ(bgk_point_segment_dist2(0.5f, 1.0f, 0.0f, 0, 0, 0, 1, 0, 0), 1.0f);
}

TEST(PointSegmentDistance, ClampedAtBothEnds) {
  EXPECT_FLOAT_EQ(bgk_point_segment_dist2(-1.0f, 1.0f, 0.0f, 0, 0, 0, 1, 0, 0), 2.0f);
  EXPECT_FLOAT_EQ(bgk_point_segment_dist2(3.0f, 0.0f, 0.0f, 0, 0, 0, 1, 0, 0), 4.0f);
}

TEST(PointSegmentDistance, ZeroLengthSegmentIsAPoint) {
  EXPECT_FLOAT_EQ(bgk_point_segment_dist2(1.0f, 2.0f, 2.0f, 1, 0, 0, 1, 0, 0), 8.0f);
  EXPECT_EQ(bgk_point_segment_dist2(1.0f, 0.0f, 0.0f, 1, 0, 0, 1, 0, 0), 0.0f);
}

TEST(PointSegmentDistance, RandomAgainstDenseSampling) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-2, 2);
  for (int trial = 0; trial < 200; ++trial) {
    const float p[3] = {u(rng), u(rng), u(rng)}, a[3] = {u(rng), u(rng), u(rng)}, b[3] = {u(rng), u(rng), u(rng)};
    double best = 1e30;
    for (int i = 0; i <= 20000; ++i) {
      const double t = i / 20000.0;
      double d2 = 0;
      for (int k = 0; k < 3; ++k) d2 += std::pow(p[k] - (a[k] + t * (b[k] - a[k])), 2);
      best = std::min(best, d2);
    }
    const float got = bgk_point_segment_dist2(p[0], p[1], p[2], a[0], a[1], a[2], b[0], b[1], b[2]);
    EXPECT_NEAR(got, best, 1e-4 + 1e-4 * best);
    EXPECT_LE(got, best + 1e-5);
  }
}

TEST(BoxKernel, PointInsideHalfOpenCell) {
  EXPECT_EQ(bgk_box_kernel_point(0.05f, 0.05f, 0.05f, 0.05f, 0.0f, 0.01f, 0.09f), 1.0f);
  EXPECT_EQ(bgk_box_kernel_point(0.05f, 0.05f, 0.05f, 0.05f, 0.1f, 0.01f, 0.09f), 0.0f);  // upper face excluded
  EXPECT_EQ(bgk_box_kernel_point(0.05f, 0.05f, 0.05f, 0.05f, 0.05f, -0.01f, 0.05f), 0.0f);
}

TEST(BoxKernel, SegmentThroughAndPastACell) {
  EXPECT_EQ(bgk_box_kernel_segment(0.05f, 0.05f, 0.05f, 0.05f, -1, 0.05f, 0.05f, 1, 0.05f, 0.05f), 1.0f);
  EXPECT_EQ(bgk_box_kernel_segment(0.05f, 0.05f, 0.05f, 0.05f, -1, 0.2f, 0.05f, 1, 0.2f, 0.05f), 0.0f);
  EXPECT_EQ(bgk_box_kernel_segment(0.05f, 0.05f, 0.05f, 0.05f, -1, 0.05f, 0.05f, -0.5f, 0.05f, 0.05f), 0.0f);
  // A zero-length segment inside the cell counts; one outside does not.
  EXPECT_EQ(bgk_box_kernel_segment(0.05f, 0.05f, 0.05f, 0.05f, 0.02f, 0.02f, 0.02f, 0.02f, 0.02f, 0.02f), 1.0f);
  EXPECT_EQ(bgk_box_kernel_segment(0.05f, 0.05f, 0.05f, 0.05f, 0.2f, 0.02f, 0.02f, 0.2f, 0.02f, 0.02f), 0.0f);
}

// The slab clip keeps exactly the parameters whose point lies in the slab: checked against
// dense sampling of s in double, away from the ends (where float rounding decides).
TEST(SlabClip, KeepsThePartInsideTheSlab) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-2.0f, 2.0f), dir(-1.0f, 1.0f);
  int clipped = 0, missed = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const float q = coord(rng), u = trial % 10 == 0 ? 0.0f : dir(rng);
    float lo = coord(rng), hi = coord(rng);
    if (lo > hi) std::swap(lo, hi);
    float s0 = -1.5f, s1 = 1.5f;
    const bool any = bgk_clip_to_slab(q, u, lo, hi, &s0, &s1);
    (any ? clipped : missed)++;
    for (int k = 0; k <= 3000; ++k) {
      const double s = -1.5 + 3.0 * k / 3000, x = double(q) + s * double(u);
      const double margin = 1e-4;
      if (x > lo + margin && x < hi - margin) {
        ASSERT_TRUE(any) << "trial " << trial;
        EXPECT_LE(s0, s + margin) << "trial " << trial;
        EXPECT_GE(s1, s - margin) << "trial " << trial;
      } else if ((x < lo - margin || x > hi + margin) && any) {
        EXPECT_TRUE(s < s0 + margin || s > s1 - margin) << "trial " << trial << " s " << s;
      }
    }
  }
  EXPECT_GT(clipped, 100);
  EXPECT_GT(missed, 100);
}

TEST(BetaPosterior, Moments) {
  CellPosterior p;
  p.alpha = 3;
  p.beta = 2;
  p.has_evidence = true;
  EXPECT_DOUBLE_EQ(p.mean(), 0.6);
  EXPECT_DOUBLE_EQ(p.variance(), 6.0 / (25.0 * 6.0));
  EXPECT_DOUBLE_EQ(p.mode(), 2.0 / 3.0);
  ClassifyParams c;
  EXPECT_EQ(p.state(c), CellState::kUnknown);  // 0.3 <= 0.6 <= 0.7
  p.alpha = 30;
  EXPECT_EQ(p.state(c), CellState::kOccupied);
  p.alpha = 0.5;
  EXPECT_EQ(p.state(c), CellState::kFree);
  EXPECT_DOUBLE_EQ(p.mode(), 0.0);  // alpha < 1 < beta: density grows towards 0
  p.has_evidence = false;
  EXPECT_EQ(p.state(c), CellState::kUnknown);
}

TEST(BetaPosterior, HighVarianceIsUnknown) {
  CellPosterior p;
  p.alpha = 0.005;
  p.beta = 0.001;
  p.has_evidence = true;
  ClassifyParams c;
  ASSERT_GT(p.mean(), c.occupied_threshold);
  ASSERT_GT(p.variance(), c.var_threshold);
  EXPECT_EQ(p.state(c), CellState::kUnknown);
}

}  // namespace
}  // namespace bgkmap
