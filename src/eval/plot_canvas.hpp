// Drawing helpers shared by the eval figures (plot_png.cpp, slice_png.cpp). Internal: includes cairo.
#pragma once

#include <cairo.h>

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace bgkmap::eval {

struct Rgb {
  double r, g, b;
};

using SurfacePtr = std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)>;
using ContextPtr = std::unique_ptr<cairo_t, decltype(&cairo_destroy)>;

// A white canvas drawing in black sans-serif.
struct Canvas {
  SurfacePtr surface;
  ContextPtr context;
  cairo_t* cr() const { return context.get(); }
};

// With `title` centred at height title_y (font size title_size).
Canvas new_canvas(int width, int height, const std::string& title, double title_y, double title_size = 14);

// The surface as a PNG, written atomically.
void write_png(const std::filesystem::path& file, cairo_surface_t* surface);

// Text with its left (align 0), centre (0.5) or right end (1) at x, baseline at y.
void text(cairo_t* cr, double x, double y, const std::string& s, double size, double align = 0);
// Text turned a quarter anticlockwise, centred on (x, y): a y axis' label.
void vertical_text(cairo_t* cr, double x, double y, const std::string& s, double size);

// v with `digits` decimals.
std::string fixed(double v, int digits);
// Tick positions covering [lo, hi] in steps of 1, 2 or 5 times a power of ten (about `count` ticks).
std::vector<double> nice_ticks(double lo, double hi, int count = 5);
// A tick's value as %g, without "-0".
std::string tick_text(double v);

// One axis: data range -> [0, 1], linear on round ticks or logarithmic on whole decades.
struct Axis {
  bool log = false;
  double lo = 0, hi = 1;
  std::vector<double> ticks;

  // From the values, or fixed ends where fixed_lo / fixed_hi are not NaN.
  static Axis fit(std::vector<double> values, bool log, double fixed_lo, double fixed_hi);
  bool shows(double v) const;
  double unit(double v) const;
  double unit_of_tick(double t) const { return (t - lo) / (hi - lo); }
  std::string tick_label(double t) const { return log ? "1e" + tick_text(t) : tick_text(t); }
};

}  // namespace bgkmap::eval
