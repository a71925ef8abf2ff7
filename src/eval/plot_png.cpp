// The eval figures through cairo's C API: the only file that includes cairo.
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/eval/plot.hpp"
#include "bgkmap/io/atomic_file.hpp"

namespace bgkmap::eval {

namespace {

struct Rgb {
  double r, g, b;
};
// Distinguishable line colours (Tableau 10).
const Rgb kSeriesColours[] = {{0.12, 0.47, 0.71}, {1.00, 0.50, 0.05}, {0.17, 0.63, 0.17}, {0.84, 0.15, 0.16},
                              {0.58, 0.40, 0.74}, {0.55, 0.34, 0.29}, {0.89, 0.47, 0.76}, {0.50, 0.50, 0.50}};

using SurfacePtr = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;
using ContextPtr = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

void write_png(const std::filesystem::path& file, cairo_surface_t* surface) {
  write_path_atomically(file, [surface](const std::filesystem::path& temp) {
    if (cairo_surface_write_to_png(surface, temp.c_str()) != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(temp.string() + ": cairo could not write the PNG");
  });
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size, double align = 0) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t ext;
  cairo_text_extents(cr, s.c_str(), &ext);
  cairo_move_to(cr, x - align * ext.width, y);
  cairo_show_text(cr, s.c_str());
}

// A white canvas drawing in black sans-serif, with `title` centred at height title_y.
struct Canvas {
  SurfacePtr surface;
  ContextPtr context;
  cairo_t* cr() const { return context.get(); }
};

Canvas new_canvas(int width, int height, const std::string& title, double title_y) {
  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  ContextPtr context(cairo_create(surface.get()), cairo_destroy);
  cairo_t* cr = context.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, width / 2.0, title_y, title, 14, 0.5);
  return {std::move(surface), std::move(context)};
}

std::string fixed(double v, int digits) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

// Axes of a unit square [0,1]^2 drawn at (x, y) with side `size`; returns nothing, draws ticks.
void draw_axes(cairo_t* cr, double x, double y, double size, const std::string& xlabel, const std::string& ylabel,
               const std::string& title) {
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1);
  cairo_rectangle(cr, x, y, size, size);
  cairo_stroke(cr);
  for (int i = 0; i <= 5; ++i) {
    const double t = i / 5.0;
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, x + t * size, y);
    cairo_line_to(cr, x + t * size, y + size);
    cairo_move_to(cr, x, y + size - t * size);
    cairo_line_to(cr, x + size, y + size - t * size);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, x + t * size, y + size + 14, fixed(t, 1), 10, 0.5);
    text(cr, x - 6, y + size - t * size + 4, fixed(t, 1), 10, 1);
  }
  text(cr, x + size / 2, y + size + 30, xlabel, 12, 0.5);
  text(cr, x + size / 2, y - 8, title, 13, 0.5);
  cairo_save(cr);
  cairo_move_to(cr, x - 30, y + size / 2);
  cairo_rotate(cr, -M_PI / 2);
  cairo_text_extents_t ext;
  cairo_set_font_size(cr, 12);
  cairo_text_extents(cr, ylabel.c_str(), &ext);
  cairo_rel_move_to(cr, -ext.width / 2, 0);
  cairo_show_text(cr, ylabel.c_str());
  cairo_restore(cr);
}

void draw_curve(cairo_t* cr, double x, double y, double size, const std::vector<double>& xs,
                const std::vector<double>& ys, const Rgb& c, bool dashed) {
  if (xs.empty()) return;
  cairo_set_source_rgb(cr, c.r, c.g, c.b);
  cairo_set_line_width(cr, 1.8);
  const double dash[] = {5, 3};
  cairo_set_dash(cr, dash, dashed ? 2 : 0, 0);
  cairo_move_to(cr, x + xs[0] * size, y + size - ys[0] * size);
  for (size_t i = 1; i < xs.size(); ++i) cairo_line_to(cr, x + xs[i] * size, y + size - ys[i] * size);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
}

Rgb variance_colour(double v) {
  // 0 .. 0.25 (the largest variance of a Beta): dark blue -> teal -> yellow.
  const double t = std::clamp(v / 0.25, 0.0, 1.0);
  if (t < 0.5) {
    const double u = t / 0.5;
    return {0.27 * (1 - u) + 0.13 * u, 0.00 * (1 - u) + 0.57 * u, 0.33 * (1 - u) + 0.55 * u};
  }
  const double u = (t - 0.5) / 0.5;
  return {0.13 * (1 - u) + 0.99 * u, 0.57 * (1 - u) + 0.91 * u, 0.55 * (1 - u) + 0.14 * u};
}

}  // namespace

void write_curves_png(const std::filesystem::path& file, const std::vector<CurveSeries>& series,
                      const std::string& title) {
  const double panel = 300, left = 60, top = 50, gap = 90;
  const int legend_h = 18 * static_cast<int>(series.size()) + 10;
  const int width = static_cast<int>(left + panel + gap + panel + 20);
  const int height = static_cast<int>(top + panel + 45 + legend_h);
  const Canvas canvas = new_canvas(width, height, title, 20);
  cairo_t* cr = canvas.cr();
  const double roc_x = left, pr_x = left + panel + gap;
  draw_axes(cr, roc_x, top, panel, "false positive rate", "true positive rate", "ROC");
  draw_axes(cr, pr_x, top, panel, "recall", "precision", "precision-recall");
  // Chance line of the ROC.
  cairo_set_source_rgb(cr, 0.6, 0.6, 0.6);
  const double dash = 4;
  cairo_set_dash(cr, &dash, 1, 0);
  cairo_move_to(cr, roc_x, top + panel);
  cairo_line_to(cr, roc_x + panel, top);
  cairo_stroke(cr);
  cairo_set_dash(cr, nullptr, 0, 0);
  for (size_t i = 0; i < series.size(); ++i) {
    const size_t colour = series[i].colour >= 0 ? static_cast<size_t>(series[i].colour) : i;
    const Rgb& c = kSeriesColours[colour % (sizeof kSeriesColours / sizeof kSeriesColours[0])];
    const bool dashed = series[i].dashed;
    draw_curve(cr, roc_x, top, panel, series[i].curves.fpr, series[i].curves.tpr, c, dashed);
    draw_curve(cr, pr_x, top, panel, series[i].curves.recall, series[i].curves.precision, c, dashed);
    const double ly = top + panel + 50 + 18 * i;
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    if (dashed) {
      draw_curve(cr, left, ly - 9, 10, {0.0, 1.6}, {0.5, 0.5}, c, true);  // a dashed stub as the key
    } else {
      cairo_rectangle(cr, left, ly - 9, 14, 10);
      cairo_fill(cr);
    }
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, left + 20, ly, series[i].label + "   AUC " + fixed(series[i].auc, 4) + "   AP " +
                                fixed(series[i].average_precision, 4), 12);
  }
  write_png(file, canvas.surface.get());
}

void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title) {
  const int w = slice.width, h = slice.height;
  const int scale = std::max(1, std::min(8, 320 / std::max(w, h)));
  const int panels = slice.has_truth ? 3 : 2;
  const int pw = w * scale, ph = h * scale, left = 20, gap = 20, top = 50, bottom = 50;
  const int width = std::max(left + panels * pw + (panels - 1) * gap + 20, 640), height = top + ph + bottom;
  const Canvas canvas = new_canvas(width, height, title + "  (z = " + fixed(slice.z, 2) + " m)", 20);
  cairo_t* cr = canvas.cr();
  auto panel = [&](int index, const std::string& name, auto colour_of) {
    const int x = left + index * (pw + gap);
    for (int j = 0; j < h; ++j)
      for (int i = 0; i < w; ++i) {
        const Rgb c = colour_of(static_cast<size_t>(j) * w + i);
        cairo_set_source_rgb(cr, c.r, c.g, c.b);
        // Row 0 is min y: drawn at the bottom, so +y points up as on a map.
        cairo_rectangle(cr, x + i * scale, top + (h - 1 - j) * scale, scale, scale);
        cairo_fill(cr);
      }
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, x - 0.5, top - 0.5, pw + 1, ph + 1);
    cairo_stroke(cr);
    text(cr, x + pw / 2.0, top - 8, name, 12, 0.5);
  };
  panel(0, "occupancy probability", [&](size_t k) {
    const double g = 1.0 - slice.mean[k];
    return Rgb{g, g, g};
  });
  if (slice.has_variance) {
    panel(1, "posterior variance", [&](size_t k) { return variance_colour(slice.variance[k]); });
  } else {
    // No variance in this format (an OctoMap tree): show where the map has evidence instead.
    panel(1, "evidence (no variance in this format)", [&](size_t k) {
      return slice.evidence[k] ? Rgb{0.13, 0.57, 0.55} : Rgb{0.93, 0.93, 0.93};
    });
  }
  if (slice.has_truth)
    panel(2, "truth", [&](size_t k) {
      switch (slice.truth[k]) {
        case TruthLabel::kOccupied: return Rgb{0, 0, 0};
        case TruthLabel::kFree: return Rgb{1, 1, 1};
        default: return Rgb{0.85, 0.72, 0.72};
      }
    });
  cairo_set_source_rgb(cr, 0, 0, 0);
  const std::string extent = "x " + fixed(slice.box.min.x, 1) + ".." + fixed(slice.box.max.x, 1) + " m, y " +
                             fixed(slice.box.min.y, 1) + ".." + fixed(slice.box.max.y, 1) + " m";
  const std::string middle = slice.has_variance ? "variance: blue 0 .. yellow 0.25" : "evidence: teal, none: grey";
  text(cr, left, top + ph + 20, extent + ";  score: white 0 .. black 1;  " + middle, 11);
  if (slice.has_truth) text(cr, left, top + ph + 38, "truth: black occupied, white free, pink outside the truth region", 11);
  write_png(file, canvas.surface.get());
}

namespace {

// Tick positions covering [lo, hi] in steps of 1, 2 or 5 times a power of ten (about five ticks).
std::vector<double> nice_ticks(double lo, double hi) {
  const double raw = (hi - lo) / 5, magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double step = magnitude * (raw / magnitude < 1.5 ? 1 : raw / magnitude < 3.5 ? 2 : raw / magnitude < 7.5 ? 5 : 10);
  std::vector<double> ticks;
  for (double t = std::floor(lo / step + 1e-9) * step; t < hi + step * 0.999; t += step) ticks.push_back(t);
  return ticks;
}

std::string tick_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", std::abs(v) < 1e-12 ? 0.0 : v);
  return buf;
}

// One axis: data range -> [0, 1], linear on round ticks or logarithmic on whole decades.
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;
  std::vector<double> ticks;

  static Axis fit(std::vector<double> values, bool log, double fixed_lo, double fixed_hi) {
    Axis a;
    a.log = log;
    if (log) values.erase(std::remove_if(values.begin(), values.end(), [](double v) { return !(v > 0); }), values.end());
    double lo = std::isnan(fixed_lo) ? (values.empty() ? (log ? 1e-3 : 0) : *std::min_element(values.begin(), values.end())) : fixed_lo;
    double hi = std::isnan(fixed_hi) ? (values.empty() ? 1 : *std::max_element(values.begin(), values.end())) : fixed_hi;
    if (log) {
      a.lo = std::floor(std::log10(lo));
      a.hi = std::max(a.lo + 1, std::ceil(std::log10(hi)));
      for (double d = a.lo; d <= a.hi + 1e-9; ++d) a.ticks.push_back(d);
      return a;
    }
    if (hi - lo < 1e-12) {
      lo -= 0.5;
      hi += 0.5;
    }
    a.ticks = nice_ticks(lo, hi);
    a.lo = std::isnan(fixed_lo) ? std::min(lo, a.ticks.front()) : lo;
    a.hi = std::isnan(fixed_hi) ? std::max(hi, a.ticks.back()) : hi;
    a.ticks.erase(std::remove_if(a.ticks.begin(), a.ticks.end(),
                                 [&](double t) { return t < a.lo - 1e-9 || t > a.hi + 1e-9; }),
                  a.ticks.end());
    return a;
  }
  bool shows(double v) const { return std::isfinite(v) && (!log || v > 0); }
  double unit(double v) const { return ((log ? std::log10(v) : v) - lo) / (hi - lo); }
  double unit_of_tick(double t) const { return (t - lo) / (hi - lo); }
  std::string tick_label(double t) const { return log ? "1e" + tick_text(t) : tick_text(t); }
};

}  // namespace

void write_line_panels_png(const std::filesystem::path& file, const std::vector<LinePanel>& panels, int columns,
                           const std::string& title) {
  if (panels.empty() || columns < 1) throw std::invalid_argument("a line plot needs panels and columns >= 1");
  std::vector<std::string> labels;  // colour i for the i-th label met
  for (const LinePanel& p : panels)
    for (const LineSeries& s : p.series)
      if (std::find(labels.begin(), labels.end(), s.label) == labels.end()) labels.push_back(s.label);
  const auto colour_of = [&](const std::string& label) {
    const size_t i = std::find(labels.begin(), labels.end(), label) - labels.begin();
    return kSeriesColours[i % (sizeof kSeriesColours / sizeof kSeriesColours[0])];
  };
  const double pw = 300, ph = 200, left = 75, top = 55, gap_x = 95, gap_y = 85;
  const int rows = (static_cast<int>(panels.size()) + columns - 1) / columns;
  const int width = static_cast<int>(left + columns * pw + (columns - 1) * gap_x + 25);
  const int height = static_cast<int>(top + rows * ph + (rows - 1) * gap_y + 50 + 18 * labels.size() + 10);
  const Canvas canvas = new_canvas(width, height, title, 22);
  cairo_t* cr = canvas.cr();
  for (size_t k = 0; k < panels.size(); ++k) {
    const LinePanel& panel = panels[k];
    const double x0 = left + static_cast<double>(k % columns) * (pw + gap_x);
    const double y0 = top + static_cast<double>(k / columns) * (ph + gap_y);
    std::vector<double> xs, ys;
    for (const LineSeries& s : panel.series) {
      xs.insert(xs.end(), s.x.begin(), s.x.end());
      for (double y : s.y)
        if (std::isfinite(y)) ys.push_back(y);
    }
    const Axis ax = Axis::fit(xs, false, std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN());
    const Axis ay = Axis::fit(ys, panel.log_y, panel.y_min, panel.y_max);
    cairo_set_line_width(cr, 1);
    for (double t : ax.ticks) {
      const double px = x0 + ax.unit_of_tick(t) * pw;
      cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
      cairo_move_to(cr, px, y0);
      cairo_line_to(cr, px, y0 + ph);
      cairo_stroke(cr);
      cairo_set_source_rgb(cr, 0, 0, 0);
      text(cr, px, y0 + ph + 14, ax.tick_label(t), 10, 0.5);
    }
    for (double t : ay.ticks) {
      const double py = y0 + ph - ay.unit_of_tick(t) * ph;
      cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
      cairo_move_to(cr, x0, py);
      cairo_line_to(cr, x0 + pw, py);
      cairo_stroke(cr);
      cairo_set_source_rgb(cr, 0, 0, 0);
      text(cr, x0 - 6, py + 4, ay.tick_label(t), 10, 1);
    }
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_rectangle(cr, x0, y0, pw, ph);
    cairo_stroke(cr);
    text(cr, x0 + pw / 2, y0 + ph + 30, panel.xlabel, 12, 0.5);
    text(cr, x0 + pw / 2, y0 - 8, panel.title, 13, 0.5);
    cairo_save(cr);
    cairo_move_to(cr, x0 - 48, y0 + ph / 2);
    cairo_rotate(cr, -M_PI / 2);
    cairo_text_extents_t ext;
    cairo_set_font_size(cr, 12);
    cairo_text_extents(cr, panel.ylabel.c_str(), &ext);
    cairo_rel_move_to(cr, -ext.width / 2, 0);
    cairo_show_text(cr, panel.ylabel.c_str());
    cairo_restore(cr);
    cairo_save(cr);
    cairo_rectangle(cr, x0, y0, pw, ph);
    cairo_clip(cr);
    for (const LineSeries& s : panel.series) {
      const Rgb c = colour_of(s.label);
      cairo_set_source_rgb(cr, c.r, c.g, c.b);
      cairo_set_line_width(cr, 1.8);
      bool drawing = false;
      for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (!ay.shows(s.y[i])) continue;
        const double px = x0 + ax.unit(s.x[i]) * pw, py = y0 + ph - ay.unit(s.y[i]) * ph;
        if (drawing) cairo_line_to(cr, px, py);
        else cairo_move_to(cr, px, py);
        drawing = true;
      }
      cairo_stroke(cr);
      for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (!ay.shows(s.y[i])) continue;
        cairo_arc(cr, x0 + ax.unit(s.x[i]) * pw, y0 + ph - ay.unit(s.y[i]) * ph, 3, 0, 2 * M_PI);
        cairo_fill(cr);
      }
    }
    cairo_restore(cr);
  }
  for (size_t i = 0; i < labels.size(); ++i) {
    const Rgb c = colour_of(labels[i]);
    const double ly = top + rows * ph + (rows - 1) * gap_y + 55 + 18 * i;
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_rectangle(cr, left, ly - 9, 14, 10);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, left + 20, ly, labels[i], 12);
  }
  write_png(file, canvas.surface.get());
}

}  // namespace bgkmap::eval
