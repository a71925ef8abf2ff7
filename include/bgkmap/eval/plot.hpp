// PNG figures of an evaluation, drawn with cairo (src/eval/plot_png.cpp, the only file that
// includes it): ROC and precision-recall curves of several maps overlaid, and a horizontal slice
// of a map (score, and variance where the format has one) beside the truth. Written atomically.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
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

// Two panels, ROC (left) and precision-recall (right), one line per series.
void write_curves_png(const std::filesystem::path& file, const std::vector<CurveSeries>& series,
                      const std::string& title);

// Cells of the plane z = const through the box, row-major (x fastest, row 0 at min y).
struct SliceImage {
  int width = 0, height = 0;
  double z = 0;
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

// Three panels: score (white free .. black occupied), variance (or, for a format without one,
// which cells have evidence), truth (left out for a slice made without truth).
void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title);

// A line through (x, y) with a marker at each point; points whose y is not finite (or not > 0 on
// a log axis) are left out.
struct LineSeries {
  std::string label;  // legend text: the same label has the same colour in every panel
  std::vector<double> x, y;
};

struct LinePanel {
  std::string title, xlabel, ylabel;
  bool log_y = false;
  // The y axis' range; NaN: from the data.
  double y_min = std::numeric_limits<double>::quiet_NaN(), y_max = std::numeric_limits<double>::quiet_NaN();
  std::vector<LineSeries> series;
};

// Panels in rows of `columns`, each with its own axes, and one legend of every label below them.
void write_line_panels_png(const std::filesystem::path& file, const std::vector<LinePanel>& panels, int columns,
                           const std::string& title);

}  // namespace bgkmap::eval
