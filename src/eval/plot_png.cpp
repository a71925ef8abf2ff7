// The eval figures of curves and lines (ROC, precision-recall, benchmark panels).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/eval/plot.hpp"
#include "eval/plot_canvas.hpp"

namespace bgkmap::eval {

namespace {

// Distinguishable line colours (Tableau 10).
const Rgb kSeriesColours[] = {{0.12, 0.47, 0.71}, {1.00, 0.50, 0.05}, {0.17, 0.63, 0.17}, {0.84, 0.15, 0.16},
                              {0.58, 0.40, 0.74}, {0.55, 0.34, 0.29}, {0.89, 0.47, 0.76}, {0.50, 0.50, 0.50}};
constexpr size_t kPaletteSize = sizeof kSeriesColours / sizeof kSeriesColours[0];
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// A panel's rectangle in pixels and its two axes.
struct Frame {
  double x, y, w, h;
  Axis ax, ay;
  double px(double v) const { return x + ax.unit(v) * w; }
  double py(double v) const { return y + h - ay.unit(v) * h; }
};

// Grid lines and tick labels at the axes' ticks, the frame, the axis labels and the title.
void draw_frame(cairo_t* cr, const Frame& f, const std::string& title, const std::string& xlabel,
                const std::string& ylabel) {
  cairo_set_line_width(cr, 1);
  for (double t : f.ax.ticks) {
    const double px = f.x + f.ax.unit_of_tick(t) * f.w;
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, px, f.y);
    cairo_line_to(cr, px, f.y + f.h);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, px, f.y + f.h + 14, f.ax.tick_label(t), 10, 0.5);
  }
  for (double t : f.ay.ticks) {
    const double py = f.y + f.h - f.ay.unit_of_tick(t) * f.h;
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, f.x, py);
    cairo_line_to(cr, f.x + f.w, py);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, f.x - 6, py + 4, f.ay.tick_label(t), 10, 1);
  }
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_rectangle(cr, f.x, f.y, f.w, f.h);
  cairo_stroke(cr);
  text(cr, f.x + f.w / 2, f.y + f.h + 30, xlabel, 12, 0.5);
  text(cr, f.x + f.w / 2, f.y - 8, title, 13, 0.5);
  vertical_text(cr, f.x - 48, f.y + f.h / 2, ylabel, 12);
}

// The points of (xs, ys) the axes show, joined (unless `joined` is false), clipped to the frame.
void draw_line(cairo_t* cr, const Frame& f, const std::vector<double>& xs, const std::vector<double>& ys, const Rgb& c,
               bool dashed, bool markers = false, bool joined = true) {
  cairo_save(cr);
  cairo_rectangle(cr, f.x, f.y, f.w, f.h);
  cairo_clip(cr);
  cairo_set_source_rgb(cr, c.r, c.g, c.b);
  cairo_set_line_width(cr, 1.8);
  const double dash[] = {5, 3};
  cairo_set_dash(cr, dash, dashed ? 2 : 0, 0);
  bool drawing = false;
  for (size_t i = 0; joined && i < xs.size() && i < ys.size(); ++i) {
    if (!f.ax.shows(xs[i]) || !f.ay.shows(ys[i])) continue;
    if (drawing) cairo_line_to(cr, f.px(xs[i]), f.py(ys[i]));
    else cairo_move_to(cr, f.px(xs[i]), f.py(ys[i]));
    drawing = true;
  }
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  if (markers)
    for (size_t i = 0; i < xs.size() && i < ys.size(); ++i) {
      if (!f.ax.shows(xs[i]) || !f.ay.shows(ys[i])) continue;
      cairo_arc(cr, f.px(xs[i]), f.py(ys[i]), 3, 0, 2 * M_PI);
      cairo_fill(cr);
    }
  cairo_restore(cr);
}

// A legend row: a swatch (or a dashed stub) and its text.
void legend_row(cairo_t* cr, double x, double y, const Rgb& c, bool dashed, const std::string& label) {
  cairo_set_source_rgb(cr, c.r, c.g, c.b);
  if (dashed) {
    const double dash[] = {5, 3};
    cairo_set_dash(cr, dash, 2, 0);
    cairo_set_line_width(cr, 1.8);
    cairo_move_to(cr, x, y - 4);
    cairo_line_to(cr, x + 16, y - 4);
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
  } else {
    cairo_rectangle(cr, x, y - 9, 14, 10);
    cairo_fill(cr);
  }
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, x + 20, y, label, 12);
}

// The lowest false positive rate the ROC's log axis shows: the series' smallest non-zero one,
// but no lower than 1e-4 (below it a few cells make the curve).
double roc_fpr_floor(const std::vector<CurveSeries>& series) {
  double lo = 1;
  for (const CurveSeries& s : series)
    for (double v : s.curves.fpr)
      if (v > 0) lo = std::min(lo, v);
  return std::clamp(lo, 1e-4, 0.1);
}

}  // namespace

void write_curves_png(const std::filesystem::path& file, const std::vector<CurveSeries>& series,
                      const std::string& title) {
  const double panel = 320, left = 75, top = 50, gap = 95;
  const int legend_h = 18 * static_cast<int>(series.size()) + 10;
  const int width = static_cast<int>(left + panel + gap + panel + 20);
  const int height = static_cast<int>(top + panel + 45 + legend_h);
  const Canvas canvas = new_canvas(width, height, title, 20);
  cairo_t* cr = canvas.cr();
  // The ROC's false positive rate on a log axis: most cells are free, so its curve rises within
  // the first percent and a linear axis would squeeze it against the left edge.
  std::vector<double> precisions;
  for (const CurveSeries& s : series)
    for (double v : s.curves.precision)
      if (std::isfinite(v)) precisions.push_back(v);
  const Frame roc{left, top, panel, panel, Axis::fit({}, true, roc_fpr_floor(series), 1), Axis::fit({}, false, 0, 1)};
  const Frame pr{left + panel + gap, top, panel, panel, Axis::fit({}, false, 0, 1),
                 Axis::fit(precisions, false, kNaN, 1)};
  draw_frame(cr, roc, "ROC", "false positive rate (log)", "true positive rate");
  draw_frame(cr, pr, "precision-recall", "recall", "precision");
  std::vector<double> chance;  // the chance line y = x, bent by the log axis
  for (int i = 0; i <= 64; ++i) chance.push_back(std::pow(10.0, roc.ax.lo + (roc.ax.hi - roc.ax.lo) * i / 64.0));
  draw_line(cr, roc, chance, chance, {0.6, 0.6, 0.6}, true);
  for (size_t i = 0; i < series.size(); ++i) {
    const size_t colour = series[i].colour >= 0 ? static_cast<size_t>(series[i].colour) : i;
    const Rgb& c = kSeriesColours[colour % kPaletteSize];
    const bool dashed = series[i].dashed;
    draw_line(cr, roc, series[i].curves.fpr, series[i].curves.tpr, c, dashed);
    draw_line(cr, pr, series[i].curves.recall, series[i].curves.precision, c, dashed);
    legend_row(cr, left, top + panel + 50 + 18 * i, c, dashed,
               series[i].label + "   AUC " + fixed(series[i].auc, 4) + "   AP " + fixed(series[i].average_precision, 4));
  }
  write_png(file, canvas.surface.get());
}

void write_line_panels_png(const std::filesystem::path& file, const std::vector<LinePanel>& panels, int columns,
                           const std::string& title) {
  if (panels.empty() || columns < 1) throw std::invalid_argument("a line plot needs panels and columns >= 1");
  std::vector<std::string> labels;  // colour i for the i-th label met
  for (const LinePanel& p : panels)
    for (const LineSeries& s : p.series)
      if (std::find(labels.begin(), labels.end(), s.label) == labels.end()) labels.push_back(s.label);
  const auto colour_of = [&](const std::string& label) {
    const size_t i = std::find(labels.begin(), labels.end(), label) - labels.begin();
    return kSeriesColours[i % kPaletteSize];
  };
  const double pw = 300, ph = 200, left = 75, top = 55, gap_x = 95, gap_y = 85;
  const int rows = (static_cast<int>(panels.size()) + columns - 1) / columns;
  const int width = static_cast<int>(left + columns * pw + (columns - 1) * gap_x + 25);
  const int height = static_cast<int>(top + rows * ph + (rows - 1) * gap_y + 50 + 18 * labels.size() + 10);
  const Canvas canvas = new_canvas(width, height, title, 22);
  cairo_t* cr = canvas.cr();
  for (size_t k = 0; k < panels.size(); ++k) {
    const LinePanel& panel = panels[k];
    std::vector<double> xs, ys;
    for (const LineSeries& s : panel.series) {
      for (double x : s.x)
        if (std::isfinite(x)) xs.push_back(x);
      for (double y : s.y)
        if (std::isfinite(y)) ys.push_back(y);
    }
    const Frame f{left + static_cast<double>(k % columns) * (pw + gap_x), top + static_cast<double>(k / columns) * (ph + gap_y),
                  pw, ph, Axis::fit(xs, panel.log_x, kNaN, kNaN), Axis::fit(ys, panel.log_y, panel.y_min, panel.y_max)};
    draw_frame(cr, f, panel.title, panel.xlabel, panel.ylabel);
    for (const LineSeries& s : panel.series) draw_line(cr, f, s.x, s.y, colour_of(s.label), false, true, s.joined);
  }
  for (size_t i = 0; i < labels.size(); ++i)
    legend_row(cr, left, top + rows * ph + (rows - 1) * gap_y + 55 + 18 * i, colour_of(labels[i]), false, labels[i]);
  write_png(file, canvas.surface.get());
}

}  // namespace bgkmap::eval
