// The eval figures through cairo's C API: the only file that includes cairo.
#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

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
                const std::vector<double>& ys, const Rgb& c) {
  if (xs.empty()) return;
  cairo_set_source_rgb(cr, c.r, c.g, c.b);
  cairo_set_line_width(cr, 1.8);
  cairo_move_to(cr, x + xs[0] * size, y + size - ys[0] * size);
  for (size_t i = 1; i < xs.size(); ++i) cairo_line_to(cr, x + xs[i] * size, y + size - ys[i] * size);
  cairo_stroke(cr);
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
  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  ContextPtr owner(cairo_create(surface.get()), cairo_destroy);
  cairo_t* cr = owner.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, width / 2.0, 20, title, 14, 0.5);
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
    const Rgb& c = kSeriesColours[i % (sizeof kSeriesColours / sizeof kSeriesColours[0])];
    draw_curve(cr, roc_x, top, panel, series[i].curves.fpr, series[i].curves.tpr, c);
    draw_curve(cr, pr_x, top, panel, series[i].curves.recall, series[i].curves.precision, c);
    const double ly = top + panel + 50 + 18 * i;
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_rectangle(cr, left, ly - 9, 14, 10);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(cr, left + 20, ly, series[i].label + "   AUC " + fixed(series[i].auc, 4) + "   AP " +
                                fixed(series[i].average_precision, 4), 12);
  }
  write_png(file, surface.get());
}

void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title) {
  const int w = slice.width, h = slice.height;
  const int scale = std::max(1, std::min(8, 320 / std::max(w, h)));
  const int pw = w * scale, ph = h * scale, left = 20, gap = 20, top = 50, bottom = 50;
  const int width = left + 3 * pw + 2 * gap + 20, height = top + ph + bottom;
  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  ContextPtr owner(cairo_create(surface.get()), cairo_destroy);
  cairo_t* cr = owner.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, width / 2.0, 20, title + "  (z = " + fixed(slice.z, 2) + " m)", 14, 0.5);
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
  panel(0, "posterior mean", [&](size_t k) {
    const double g = 1.0 - slice.mean[k];
    return Rgb{g, g, g};
  });
  panel(1, "posterior variance", [&](size_t k) { return variance_colour(slice.variance[k]); });
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
  text(cr, left, top + ph + 20, extent + ";  mean: white 0 .. black 1;  variance: blue 0 .. yellow 0.25", 11);
  text(cr, left, top + ph + 38, "truth: black occupied, white free, pink outside the truth region", 11);
  write_png(file, surface.get());
}

}  // namespace bgkmap::eval
