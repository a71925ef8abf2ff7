// PNG figures of an evaluation, drawn with cairo (src/eval/plot_png.cpp, the only file that
// includes it): ROC and precision-recall curves of several maps overlaid, and a horizontal slice
// of a map (posterior mean and variance) beside the truth. Written atomically.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/eval/truth.hpp"

namespace bgkmap::eval {

struct CurveSeries {
  std::string label;  // legend text, e.g. the map file name
  Curves curves;
  double auc = 0, average_precision = 0;
};

// Two panels, ROC (left) and precision-recall (right), one coloured line per series.
void write_curves_png(const std::filesystem::path& file, const std::vector<CurveSeries>& series,
                      const std::string& title);

// Cells of the plane z = const through the box, row-major (x fastest, row 0 at min y).
struct SliceImage {
  int width = 0, height = 0;
  double z = 0;
  sim::Box3d box;
  std::vector<double> mean, variance;
  std::vector<TruthLabel> truth;  // kUnknown everywhere when no truth is given
  std::vector<uint8_t> evidence;  // 1 where the map has evidence
};

// The map's cells (and the truth's labels, when `truth` is given) on the horizontal plane at z,
// over box's x/y extent. Throws std::invalid_argument when the slice would be empty or huge.
SliceImage make_slice(const BgkMap& map, const Truth* truth, const sim::Box3d& box, double z);

// Three panels: mean (white free .. black occupied), variance, truth.
void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title);

}  // namespace bgkmap::eval
