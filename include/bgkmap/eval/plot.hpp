// PNG figures of an evaluation, drawn with cairo (src/eval/plot_png.cpp and slice_png.cpp): ROC
// and precision-recall curves of several maps overlaid, and a horizontal slice of a map (score,
// and variance where the format has one) beside the truth. Written atomically.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/eval/truth.hpp"

namespace bgkmap::eval {

struct CurveSeries {
  std::string label;  // legend text, e.g. the map file name
  Curves curves;
  double auc = 0, average_precision = 0;
  int colour = -1;      // index into the palette; -1: the series' position
  bool dashed = false;  // e.g. a second protocol of the same map, in the map's colour
};

// Two panels, ROC (left, false positive rate on a log axis) and precision-recall (right), one
// line per series.
void write_curves_png(const std::filesystem::path& file, const std::vector<CurveSeries>& series,
                      const std::string& title);

// Cells of the plane z = const through the box, row-major (x fastest, row 0 at min y).
struct SliceImage {
  int width = 0, height = 0;
  double z = 0;
  double resolution = 0;  // metres per cell
  int32_t x0 = 0, y0 = 0;  // index of the cell at column 0, row 0
  sim::Box3d box;
  std::vector<double> mean;      // the map's score (kUnknownScore where it has no evidence)
  bool has_variance = false;
  std::vector<double> variance;  // empty without has_variance
  bool has_truth = false;
  std::vector<TruthLabel> truth;  // kUnknown everywhere when no truth is given
  std::vector<uint8_t> evidence;  // 1 where the map has evidence
};

// The map's cells (and the truth's labels, when `truth` is given) on the horizontal plane at z,
// over box's x/y extent. Throws std::invalid_argument when the slice would be empty or huge.
SliceImage make_slice(const ScoredMap& map, const Truth* truth, const sim::Box3d& box, double z);

// The height of the centre of the layer (cells of one z index) holding the most wall cells:
// occupied, with occupied cells right above and below, beside a cell the map scores free. A
// building's walls, not its floor or ceiling. A map without such cells (a planar one): its layer
// with the most occupied cells. Of equal counts the highest layer. nullopt when the map scores no
// cell occupied.
std::optional<double> busiest_layer_z(const ScoredMap& map);

// The picture's longest side at most (pixels): a larger slice is drawn several cells a pixel.
constexpr int kMaxSlicePixels = 2000;

// Where write_slice_png draws, in pixels from the top-left corner.
struct SliceLayout {
  struct Rect {
    int x = 0, y = 0, w = 0, h = 0;
  };
  int width = 0, height = 0;   // the picture
  int upscale = 1;             // a cell is upscale x upscale pixels (when downscale is 1)
  int downscale = 1;           // a pixel is downscale x downscale cells, the most occupied shown
  std::vector<Rect> panels;    // the cells' pixels: score, variance (or evidence), truth
  Rect scale_bar;              // the black bar under the score panel
  double scale_bar_m = 0;      // its length in metres
  // The pixel of cell (column i, row j) in panel p (row 0, min y, at the bottom).
  std::pair<int, int> pixel(size_t p, int i, int j) const;
};
SliceLayout slice_layout(const SliceImage& slice);

// Panels side by side (or stacked, for a map much wider than tall): score (white free .. black
// occupied, grey no evidence), variance (or, for a format without one, which cells have
// evidence), truth (left out for a slice made without truth); each with axes in metres, the
// score panel with a scale bar, each with its colour bar or key.
void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title);

// A line through (x, y) with a marker at each point (or the markers alone); points that are not
// finite (or not > 0 on a log axis) are left out.
struct LineSeries {
  std::string label;  // legend text: the same label has the same colour in every panel
  std::vector<double> x, y;
  bool joined = true;  // false: markers only (points in no order, e.g. an optimiser's trials)
};

struct LinePanel {
  std::string title, xlabel, ylabel;
  bool log_x = false, log_y = false;
  // The y axis' range; NaN: from the data.
  double y_min = std::numeric_limits<double>::quiet_NaN(), y_max = std::numeric_limits<double>::quiet_NaN();
  std::vector<LineSeries> series;
};

// Panels in rows of `columns`, each with its own axes, and one legend of every label below them.
void write_line_panels_png(const std::filesystem::path& file, const std::vector<LinePanel>& panels, int columns,
                           const std::string& title);

}  // namespace bgkmap::eval
