// Preprocessing: non-finite points, max range, end margin, frames, downsampling.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bgkmap/integrate/observations.hpp"

namespace bgkmap {
namespace {

Scan scan_from_origin(const std::vector<Vec3f>& points) {
  Scan s;
  s.pose.position = {1, 2, 0};
  s.points = points;
  return s;
}

TEST(Preprocess, DropsAndCountsNonFinitePoints) {
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  const Scan s = scan_from_origin({{2, 2, 0}, {nan, 0, 0}, {0, inf, 0}, {0, 0, -inf}, {4, 2, 0}});
  PreprocessParams params;
  params.end_margin_m = 0;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(s, params, obs, counts);
  EXPECT_EQ(counts.points_read, 5u);
  EXPECT_EQ(counts.dropped_nonfinite, 3u);
  EXPECT_EQ(counts.hits, 2u);
  EXPECT_EQ(counts.beams, 2u);
  ASSERT_EQ(obs.hits.size(), 2u);
  EXPECT_FLOAT_EQ(obs.hits[1].x, 4.0f);
}

TEST(Preprocess, EmptyScanIsFine) {
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan_from_origin({}), PreprocessParams{}, obs, counts);
  EXPECT_TRUE(obs.hits.empty());
  EXPECT_TRUE(obs.free_ends.empty());
  EXPECT_EQ(counts.points_read, 0u);
}

TEST(Preprocess, BeyondMaxRangeGivesAFreeBeamOfMaxRangeAndNoHit) {
  PreprocessParams params;
  params.max_range_m = 5;
  params.end_margin_m = 0.5;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan_from_origin({{11, 2, 0}, {4, 2, 0}}), params, obs, counts);
  EXPECT_EQ(counts.beyond_max_range, 1u);
  ASSERT_EQ(obs.hits.size(), 1u);
  ASSERT_EQ(obs.free_ends.size(), 2u);
  EXPECT_FLOAT_EQ(obs.free_ends[0].x, 6.0f);  // 1 + 5: full max range, no margin (no surface there)
  EXPECT_FLOAT_EQ(obs.free_ends[1].x, 3.5f);  // 4 - 0.5: stops short of the hit
  EXPECT_FLOAT_EQ(obs.free_ends[1].y, 2.0f);
}

TEST(Preprocess, BeyondMaxRangeIsDroppedWhenAsked) {
  PreprocessParams params;
  params.max_range_m = 5;
  params.end_margin_m = 0.5;
  params.beyond_range = BeyondRange::kDrop;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan_from_origin({{11, 2, 0}, {4, 2, 0}, {1, 2, 7}}), params, obs, counts);
  EXPECT_EQ(counts.beyond_max_range, 2u);
  EXPECT_EQ(counts.hits, 1u);
  EXPECT_EQ(counts.beams, 1u);
  ASSERT_EQ(obs.hits.size(), 1u);
  ASSERT_EQ(obs.free_ends.size(), 1u);
  EXPECT_FLOAT_EQ(obs.free_ends[0].x, 3.5f);  // only the return within range
}

TEST(Preprocess, HitCloserThanTheMarginHasNoFreeSegment) {
  PreprocessParams params;
  params.end_margin_m = 0.5;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan_from_origin({{1.3f, 2, 0}}), params, obs, counts);
  EXPECT_EQ(obs.hits.size(), 1u);
  EXPECT_TRUE(obs.free_ends.empty());
  EXPECT_EQ(counts.beams_shorter_than_margin, 1u);
}

TEST(Preprocess, ApplyViewpointTransformsSensorFramePointsOnce) {
  Scan s = scan_from_origin({{1, 0, 0}});
  // 90 degrees about z: sensor x -> world y.
  s.pose.qw = std::sqrt(0.5f);
  s.pose.qz = std::sqrt(0.5f);
  PreprocessParams params;
  params.apply_viewpoint = true;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(s, params, obs, counts);
  ASSERT_EQ(obs.hits.size(), 1u);
  EXPECT_NEAR(obs.hits[0].x, 1.0f, 1e-6);
  EXPECT_NEAR(obs.hits[0].y, 3.0f, 1e-6);
  // A reader that already produced world-frame points (OctoMap graphs) is left alone.
  s.points_in_world_frame = true;
  preprocess_scan(s, params, obs, counts);
  EXPECT_NEAR(obs.hits[0].x, 1.0f, 1e-6);
  EXPECT_NEAR(obs.hits[0].y, 0.0f, 1e-6);
}

TEST(Preprocess, DownsamplingKeepsOnePointPerLeafAndCountsTheRest) {
  std::vector<Vec3f> points;
  for (int i = 0; i < 10; ++i) points.push_back({3.01f + 0.001f * i, 2.05f, 0.05f});  // one 0.1 m leaf
  points.push_back({5.05f, 2.05f, 0.05f});
  PreprocessParams params;
  params.downsample_m = 0.1;
  ScanObservations obs;
  PreprocessCounts counts;
  preprocess_scan(scan_from_origin(points), params, obs, counts);
  EXPECT_EQ(obs.hits.size(), 2u);
  EXPECT_EQ(counts.removed_by_downsampling, 9u);
}

}  // namespace
}  // namespace bgkmap

namespace bgkmap {
namespace {

TEST(Preprocess, DownsamplingWorksOnScansSpanningHundredsOfMetres) {
  // 0.1 m leaves over 400 m need more than 2^31 of them: PCL alone would return the input.
  std::vector<Vec3f> points;
  for (int i = 0; i < 50; ++i) {
    points.push_back({-200.0f + 0.001f * i, 0.05f, 0.05f});
    points.push_back({200.0f + 0.001f * i, 150.05f, 30.05f});
    points.push_back({0.51f + 0.001f * i, 0.05f, 0.05f});
  }
  const std::vector<Vec3f> kept = voxel_downsample(points, 0.1);
  EXPECT_EQ(kept.size(), 3u);
}

}  // namespace
}  // namespace bgkmap
