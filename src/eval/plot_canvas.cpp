#include "eval/plot_canvas.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "bgkmap/io/atomic_file.hpp"

namespace bgkmap::eval {

Canvas new_canvas(int width, int height, const std::string& title, double title_y, double title_size) {
  SurfacePtr surface(cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height), cairo_surface_destroy);
  ContextPtr context(cairo_create(surface.get()), cairo_destroy);
  cairo_t* cr = context.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_source_rgb(cr, 0, 0, 0);
  text(cr, width / 2.0, title_y, title, title_size, 0.5);
  return {std::move(surface), std::move(context)};
}

void write_png(const std::filesystem::path& file, cairo_surface_t* surface) {
  write_path_atomically(file, [surface](const std::filesystem::path& temp) {
    if (cairo_surface_write_to_png(surface, temp.c_str()) != CAIRO_STATUS_SUCCESS)
      throw std::runtime_error(temp.string() + ": cairo could not write the PNG");
  });
}

void text(cairo_t* cr, double x, double y, const std::string& s, double size, double align) {
  cairo_set_font_size(cr, size);
  cairo_text_extents_t ext;
  cairo_text_extents(cr, s.c_str(), &ext);
  cairo_move_to(cr, x - align * ext.width, y);
  cairo_show_text(cr, s.c_str());
}

void vertical_text(cairo_t* cr, double x, double y, const std::string& s, double size) {
  cairo_save(cr);
  cairo_move_to(cr, x, y);
  cairo_rotate(cr, -M_PI / 2);
  cairo_text_extents_t ext;
  cairo_set_font_size(cr, size);
  cairo_text_extents(cr, s.c_str(), &ext);
  cairo_rel_move_to(cr, -ext.width / 2, 0);
  cairo_show_text(cr, s.c_str());
  cairo_restore(cr);
}

std::string fixed(double v, int digits) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.*f", digits, v);
  return buf;
}

std::vector<double> nice_ticks(double lo, double hi, int count) {
  const double raw = (hi - lo) / count, magnitude = std::pow(10.0, std::floor(std::log10(raw)));
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

Axis Axis::fit(std::vector<double> values, bool log, double fixed_lo, double fixed_hi) {
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

bool Axis::shows(double v) const { return std::isfinite(v) && (!log || v > 0); }

double Axis::unit(double v) const { return ((log ? std::log10(v) : v) - lo) / (hi - lo); }

}  // namespace bgkmap::eval
