// The figures a person reads: render's default layer against hand-counted cells, the slice
// picture's pixels (walls, free space, scale bar, the size cap) read back from the PNG, and the
// ROC panel spreading a curve that rises within the first percent of false positives.
#include <cairo.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "bgkmap/eval/plot.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/tune/objective_plot.hpp"
#include "support/test_support.hpp"

namespace bgkmap::eval {
namespace {

// A map of 0.1 m cells: the given occupied cells (score 0.9), free (0.1) elsewhere in the box
// x, y in [0, 100), z in [1, 20] of cell indices, no evidence outside it.
class CellsMap final : public ScoredMap {
 public:
  explicit CellsMap(std::vector<CellIndex> cells) : ScoredMap(0.1), cells_(std::move(cells)) {
    for (const CellIndex& c : cells_) set_.insert({c.x, c.y, c.z});
  }
  sim::Box3d observed_bounds() const override { return sim::Box3d::empty(); }
  MapSample sample(double x, double y, double z) const override {
    const CellIndex c{int32_t(std::floor(x / 0.1)), int32_t(std::floor(y / 0.1)), int32_t(std::floor(z / 0.1))};
    if (set_.count({c.x, c.y, c.z})) return {0.9, true, std::nullopt};
    if (c.x >= 0 && c.x < 100 && c.y >= 0 && c.y < 100 && c.z >= 1 && c.z <= 20) return {0.1, true, std::nullopt};
    return {};
  }
  bool has_variance() const override { return false; }
  double occupied_threshold() const override { return 0.5; }
  std::vector<CellIndex> occupied_cells() const override { return cells_; }

 private:
  std::vector<CellIndex> cells_;
  std::set<std::tuple<int32_t, int32_t, int32_t>> set_;
};

TEST(RenderLayer, WallsWinOverTheFloorAndCeilingAPlanarMapItsFullestLayer) {
  std::vector<CellIndex> cells;
  for (int x = 0; x < 100; ++x)
    for (int y = 0; y < 100; ++y) {
      for (int z = -2; z <= 0; ++z) cells.push_back({x, y, z});  // a floor three cells thick: 10,000 a layer
      cells.push_back({x, y, 21});                                // ceiling
    }
  for (int z = 1; z <= 20; ++z)
    for (int x = 0; x < 50; ++x) cells.push_back({x, 7, z});  // a wall: 50 cells in each of layers 1..20
  for (int z = 3; z <= 8; ++z) cells.push_back({80, 80, z});  // a pillar: layers 4..7 hold 51 wall cells
  for (int x = 60; x < 90; ++x) cells.push_back({x, 40, 5});  // a table top: nothing above or below it
  const std::optional<double> z = busiest_layer_z(CellsMap(cells));
  ASSERT_TRUE(z.has_value());
  EXPECT_NEAR(*z, 0.75, 1e-12);  // layer 7, the highest of 4..7, at its centre

  std::vector<CellIndex> planar;  // one layer at z index -1 with 30 cells, one at 0 with 20
  for (int x = 0; x < 30; ++x) planar.push_back({x, 0, -1});
  for (int x = 0; x < 20; ++x) planar.push_back({x, 5, 0});
  EXPECT_NEAR(busiest_layer_z(CellsMap(planar)).value(), -0.05, 1e-12);
  for (int x = 0; x < 10; ++x) planar.push_back({x, 9, 0});  // now 30 and 30: the upper one
  EXPECT_NEAR(busiest_layer_z(CellsMap(planar)).value(), 0.05, 1e-12);
  EXPECT_FALSE(busiest_layer_z(CellsMap({})).has_value());
}

// A slice of w x h cells at 0.1 m: unknown (0.5) everywhere, a one-cell wall at column
// `wall` (0.95, variance 0.01) and free cells (0.05, variance 0.002) right of it.
SliceImage wall_slice(int w, int h, int wall) {
  SliceImage s;
  s.width = w;
  s.height = h;
  s.resolution = 0.1;
  s.x0 = -50;
  s.y0 = 20;
  s.z = 1.05;
  s.box = sim::Box3d{{-5, 2, 1}, {-5 + w * 0.1, 2 + h * 0.1, 1.1}};
  const size_t n = static_cast<size_t>(w) * h;
  s.mean.assign(n, 0.5);
  s.has_variance = true;
  s.variance.assign(n, 0.25);
  s.truth.assign(n, TruthLabel::kUnknown);
  s.evidence.assign(n, 0);
  for (int j = 0; j < h; ++j)
    for (int i = wall; i < w; ++i) {
      const size_t k = static_cast<size_t>(j) * w + i;
      s.mean[k] = i == wall ? 0.95 : 0.05;
      s.variance[k] = i == wall ? 0.01 : 0.002;
      s.evidence[k] = 1;
    }
  return s;
}

struct Png {
  std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)> surface{nullptr, cairo_surface_destroy};
  int width() const { return cairo_image_surface_get_width(surface.get()); }
  int height() const { return cairo_image_surface_get_height(surface.get()); }
  // The pixel's red, green and blue, 0..255.
  std::array<int, 3> rgb(int x, int y) const {
    const unsigned char* row = cairo_image_surface_get_data(surface.get()) + y * cairo_image_surface_get_stride(surface.get());
    const uint32_t v = reinterpret_cast<const uint32_t*>(row)[x];
    return {static_cast<int>((v >> 16) & 255), static_cast<int>((v >> 8) & 255), static_cast<int>(v & 255)};
  }
};

Png read_png(const std::filesystem::path& file) {
  Png png;
  png.surface.reset(cairo_image_surface_create_from_png(file.c_str()));
  EXPECT_EQ(cairo_surface_status(png.surface.get()), CAIRO_STATUS_SUCCESS) << file;
  return png;
}

void expect_grey(const Png& png, std::pair<int, int> at, int level, const char* what) {
  const auto [r, g, b] = png.rgb(at.first, at.second);
  EXPECT_NEAR(r, level, 2) << what << " at " << at.first << ", " << at.second;
  EXPECT_EQ(r, g) << what;
  EXPECT_EQ(g, b) << what;
}

TEST(SlicePicture, WallFreeUnknownAndTheScaleBarAtTheirPixels) {
  const auto dir = testing::make_temp_dir("slice-picture");
  const SliceImage s = wall_slice(150, 100, 60);
  write_slice_png(dir / "s.png", s, "wall");
  const SliceLayout l = slice_layout(s);
  const Png png = read_png(dir / "s.png");
  ASSERT_EQ(png.width(), l.width);
  ASSERT_EQ(png.height(), l.height);
  EXPECT_EQ(l.downscale, 1);
  EXPECT_EQ(l.upscale, 4);  // 600 px for the longest side: 150 cells of 4 px
  ASSERT_EQ(l.panels.size(), 2u);
  EXPECT_EQ(l.panels[0].w, 600);
  EXPECT_EQ(l.panels[0].h, 400);
  // Score: 1 - p as grey, the wall black, free space white, no evidence mid-grey.
  expect_grey(png, l.pixel(0, 60, 50), 13, "wall");
  expect_grey(png, l.pixel(0, 61, 0), 242, "free");
  expect_grey(png, l.pixel(0, 149, 99), 242, "free corner");
  expect_grey(png, l.pixel(0, 59, 50), 128, "unknown");
  expect_grey(png, l.pixel(0, 0, 0), 128, "unknown corner");
  // Row 0 (min y) is at the bottom: its pixel lies below row 99's.
  EXPECT_GT(l.pixel(0, 0, 0).second, l.pixel(0, 0, 99).second);
  // Variance: the colour bar's yellow at 0.25 where nothing is known, dark blue on free cells.
  const auto unknown = png.rgb(l.pixel(1, 10, 10).first, l.pixel(1, 10, 10).second);
  EXPECT_GT(unknown[0], 240);
  EXPECT_GT(unknown[1], 220);
  EXPECT_LT(unknown[2], 60);
  const auto free = png.rgb(l.pixel(1, 100, 10).first, l.pixel(1, 100, 10).second);
  EXPECT_LT(free[1], 30);
  EXPECT_GT(free[2], 70);
  // The frame is drawn just outside the cells.
  expect_grey(png, {l.panels[0].x - 1, l.panels[0].y + 10}, 0, "frame");
  // The scale bar: a round length, 4 px a cell of 0.1 m, black along its whole length.
  EXPECT_EQ(l.scale_bar_m, 2.0);  // at most 120 px: 3 m would be, 2 is the round length under it
  EXPECT_EQ(l.scale_bar.w, 80);
  for (int x = l.scale_bar.x; x < l.scale_bar.x + l.scale_bar.w; ++x)
    expect_grey(png, {x, l.scale_bar.y + l.scale_bar.h / 2}, 0, "scale bar");
  expect_grey(png, {l.scale_bar.x + l.scale_bar.w + 1, l.scale_bar.y + l.scale_bar.h / 2}, 255, "after the bar");
  std::filesystem::remove_all(dir);
}

TEST(SlicePicture, ALargeMapIsCappedAndKeepsAOneCellWall) {
  const auto dir = testing::make_temp_dir("slice-cap");
  const SliceImage s = wall_slice(5000, 700, 3001);  // 5000 cells: 1 px a cell would be 10,000 px wide
  write_slice_png(dir / "s.png", s, "wide");
  const SliceLayout l = slice_layout(s);
  const Png png = read_png(dir / "s.png");
  EXPECT_LE(png.width(), kMaxSlicePixels);
  EXPECT_LE(png.height(), kMaxSlicePixels);
  EXPECT_EQ(png.width(), l.width);
  // Stacked (one column of 1,904 px for 5000 cells: 3 cells a pixel) beats side by side (6 a pixel).
  EXPECT_EQ(l.downscale, 3);
  EXPECT_EQ(l.panels[1].x, l.panels[0].x);
  EXPECT_GT(l.panels[1].y, l.panels[0].y + l.panels[0].h);
  // Column 3001 shares its pixel with 3000 (unknown) and 3002 (free): the wall is what it shows.
  for (int j : {0, 350, 699}) expect_grey(png, l.pixel(0, 3001, j), 13, "one-cell wall");
  expect_grey(png, l.pixel(0, 3003, 350), 242, "free");
  expect_grey(png, l.pixel(0, 2000, 350), 128, "unknown");
  std::filesystem::remove_all(dir);
}

TEST(CurvesPicture, TheRocOfAMostlyFreeMapSpreadsAcrossItsPanel) {
  const auto dir = testing::make_temp_dir("roc-picture");
  // 1000 occupied cells scored evenly over 0.5 .. 1, 10,000 free ones placed so that the false
  // positive rate is 10^(-4 (1 - tpr)): it climbs from 1e-4 to 1 while the true positive rate does 0 .. 1.
  LabelledScores scores;
  for (int i = 0; i < 1000; ++i) scores.positive.push_back(0.5 + 0.5 * (i + 0.5) / 1000);
  for (int k = 1; k <= 10000; ++k) scores.negative.push_back(0.5 + std::log10(10000.0 / k) / 8);
  write_curves_png(dir / "roc.png", {{"m", compute_curves(scores), 0.95, 0.9, 0, false}}, "test");
  const Png png = read_png(dir / "roc.png");
  // The series' blue (Tableau 10's first) where the curve crosses true positive rates 0.3 .. 0.7:
  // rows 146 .. 274 of the ROC panel (top 50, 320 px high), in the left half of the picture.
  int lo = png.width(), hi = -1;
  for (int y = 146; y <= 274; ++y)
    for (int x = 0; x < png.width() / 2; ++x) {
      const auto [r, g, b] = png.rgb(x, y);
      if (std::abs(r - 31) < 25 && std::abs(g - 120) < 25 && std::abs(b - 181) < 25) {
        lo = std::min(lo, x);
        hi = std::max(hi, x);
      }
    }
  ASSERT_GE(hi, 0) << "no curve drawn";
  // Those are false positive rates 0.0016 .. 0.063: 20 px of a linear axis of 320, 1.6 of the
  // log axis' four decades (128 px).
  EXPECT_GT(hi - lo, 100) << lo << " .. " << hi;
  std::filesystem::remove_all(dir);
}

// The number of pixels in columns [x0, x1), rows [y0, y1) within 25 of colour (r, g, b).
int pixels_of(const Png& png, int x0, int x1, int y0, int y1, std::array<int, 3> colour) {
  int n = 0;
  for (int y = y0; y < y1; ++y)
    for (int x = x0; x < x1; ++x) {
      const auto [r, g, b] = png.rgb(x, y);
      n += std::abs(r - colour[0]) < 25 && std::abs(g - colour[1]) < 25 && std::abs(b - colour[2]) < 25;
    }
  return n;
}

TEST(TunePicture, EachParameterHasItsPanelOfTrialMarkersWithTheChoiceMarked) {
  const auto dir = testing::make_temp_dir("tune-picture");
  tune::TuneResult r;
  r.names = {"ell", "prior_alpha", "prior_beta"};
  for (size_t i = 0; i < 12; ++i) {
    tune::Trial t;
    t.index = i;
    t.phase = i == 3 ? "start" : "global";
    t.values = {0.1 + 0.05 * static_cast<double>(i), std::pow(10.0, -3.0 + 0.3 * i), std::pow(10.0, -2.0 + 0.2 * i)};
    t.objective = 0.2 + 0.01 * std::abs(static_cast<double>(i) - 7);
    r.trials.push_back(t);
  }
  r.trials[5].error = "failed";  // left out
  r.defaults = r.trials[3].values;  // inside every axis (a marker at an axis end is half clipped)
  r.chosen = r.trials[7].values;
  tune::write_objective_plot(dir / "t.png", "bgkl", r, tune::Objective::kNll);
  const Png png = read_png(dir / "t.png");
  // Three panels of 300 x 200 px in one row (left 75, gaps 95), a legend of three labels below.
  ASSERT_EQ(png.width(), 75 + 3 * 300 + 2 * 95 + 25);
  ASSERT_EQ(png.height(), 55 + 200 + 50 + 18 * 3 + 10);
  const std::array<int, 3> trial_blue{31, 120, 181}, chosen_green{43, 161, 43}, given_orange{255, 128, 13};
  for (int k = 0; k < 3; ++k) {
    const int x0 = 75 + k * (300 + 95);
    const int blue = pixels_of(png, x0, x0 + 300, 55, 255, trial_blue);
    // Ten markers of radius 3 (about 30 px each, fewer where they overlap), no line joining them
    // (a line back and forth across the panel would be thousands of pixels).
    EXPECT_GT(blue, 100) << "panel " << k;
    EXPECT_LT(blue, 11 * 40) << "panel " << k;
    EXPECT_GT(pixels_of(png, x0, x0 + 300, 55, 255, chosen_green), 10) << "panel " << k;
    EXPECT_GT(pixels_of(png, x0, x0 + 300, 55, 255, given_orange), 10) << "panel " << k;
  }
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::eval
