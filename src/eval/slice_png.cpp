// The slice figure: a map's cells on one plane, with axes in metres, a scale bar and colour bars.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <tuple>
#include <vector>

#include "bgkmap/eval/plot.hpp"
#include "eval/plot_canvas.hpp"

namespace bgkmap::eval {

namespace {

// Margins in pixels: the y axis' labels on the left, the title on top, under each panel its x
// axis, then the scale bar and colour bar.
constexpr int kLeft = 72, kRight = 24, kTop = 58, kGapX = 84, kGapY = 34, kBelow = 92, kMinColumn = 360;
// Cells of a small map are drawn up to this many pixels a panel's longest side.
constexpr int kTargetPanelPixels = 600;

struct Grid2 {
  int columns, rows;
};

// The picture's size for panels of pw x ph pixels in the given grid.
std::pair<int, int> picture_size(Grid2 g, int pw, int ph) {
  const int column = std::max(pw, kMinColumn);
  return {kLeft + g.columns * column + (g.columns - 1) * kGapX + kRight, kTop + g.rows * (ph + kBelow) + (g.rows - 1) * kGapY};
}

// Pixels per cell (upscale) or cells per pixel (downscale) for the grid, under the cap.
SliceLayout fit(const SliceImage& s, Grid2 g) {
  SliceLayout l;
  l.upscale = std::clamp(kTargetPanelPixels / std::max(s.width, s.height), 1, 8);
  const int avail_w = std::max(1, (kMaxSlicePixels - kLeft - kRight - (g.columns - 1) * kGapX) / g.columns);
  const int avail_h = std::max(1, (kMaxSlicePixels - picture_size(g, 0, 0).second) / g.rows);
  while (l.upscale > 1 && (s.width * l.upscale > avail_w || s.height * l.upscale > avail_h)) --l.upscale;
  if (s.width > avail_w || s.height > avail_h)
    l.downscale = std::max((s.width + avail_w - 1) / avail_w, (s.height + avail_h - 1) / avail_h);
  return l;
}

double pixels_per_cell(const SliceLayout& l) { return l.downscale > 1 ? 1.0 / l.downscale : l.upscale; }

// The largest of 1, 2, 5 times a power of ten at most `most`.
double round_down_nice(double most) {
  const double magnitude = std::pow(10.0, std::floor(std::log10(most)));
  for (double m : {5.0, 2.0, 1.0})
    if (m * magnitude <= most) return m * magnitude;
  return magnitude;
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

Rgb score_colour(double score) { return {1 - score, 1 - score, 1 - score}; }

const Rgb kEvidence{0.13, 0.57, 0.55}, kNoEvidence{0.93, 0.93, 0.93};
const Rgb kTruthOccupied{0, 0, 0}, kTruthFree{1, 1, 1}, kTruthOutside{0.85, 0.72, 0.72};

// One panel's cells as an image, a pixel per cell (upscaled) or per block of cells (downscaled,
// showing the block's cell of the highest rank, so that a thin wall stays in the picture).
SurfacePtr panel_image(const SliceImage& s, const SliceLayout& l, const std::function<Rgb(size_t)>& colour,
                       const std::function<double(size_t)>& rank) {
  const int d = l.downscale, pw = (s.width + d - 1) / d, ph = (s.height + d - 1) / d;
  SurfacePtr image(cairo_image_surface_create(CAIRO_FORMAT_RGB24, pw, ph), cairo_surface_destroy);
  cairo_surface_flush(image.get());
  unsigned char* data = cairo_image_surface_get_data(image.get());
  const int stride = cairo_image_surface_get_stride(image.get());
  for (int pj = 0; pj < ph; ++pj)
    for (int pi = 0; pi < pw; ++pi) {
      size_t best = 0;
      double best_rank = -INFINITY;
      for (int j = pj * d; j < std::min(s.height, (pj + 1) * d); ++j)
        for (int i = pi * d; i < std::min(s.width, (pi + 1) * d); ++i) {
          const size_t k = static_cast<size_t>(j) * s.width + i;
          const double r = rank(k);
          if (r > best_rank) best_rank = r, best = k;
        }
      const Rgb c = colour(best);
      // Row 0 is min y: at the bottom, so that +y points up as on a map.
      auto* px = reinterpret_cast<uint32_t*>(data + static_cast<size_t>(ph - 1 - pj) * stride) + pi;
      const auto byte = [](double v) { return static_cast<uint32_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255)); };
      *px = (byte(c.r) << 16) | (byte(c.g) << 8) | byte(c.b);
    }
  cairo_surface_mark_dirty(image.get());
  return image;
}

// Ticks and labels in metres along the panel's bottom and left edges.
void draw_metre_axes(cairo_t* cr, const SliceImage& s, const SliceLayout& l, const SliceLayout::Rect& p) {
  const double ppm = pixels_per_cell(l) / s.resolution;
  const double x_lo = s.x0 * s.resolution, y_lo = s.y0 * s.resolution;
  const double x_hi = x_lo + p.w / ppm, y_hi = y_lo + p.h / ppm;
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1);
  for (double t : nice_ticks(x_lo, x_hi, std::max(2, p.w / 110))) {
    if (t < x_lo - 1e-9 || t > x_hi + 1e-9) continue;
    const double x = std::round(p.x + (t - x_lo) * ppm) + 0.5;
    cairo_move_to(cr, x, p.y + p.h);
    cairo_line_to(cr, x, p.y + p.h + 5);
    cairo_stroke(cr);
    text(cr, x, p.y + p.h + 18, tick_text(t), 11, 0.5);
  }
  for (double t : nice_ticks(y_lo, y_hi, std::max(2, p.h / 90))) {
    if (t < y_lo - 1e-9 || t > y_hi + 1e-9) continue;
    const double y = std::round(p.y + p.h - (t - y_lo) * ppm) + 0.5;
    cairo_move_to(cr, p.x - 5, y);
    cairo_line_to(cr, p.x, y);
    cairo_stroke(cr);
    text(cr, p.x - 8, y + 4, tick_text(t), 11, 1);
  }
  text(cr, p.x + p.w / 2.0, p.y + p.h + 34, "x (m)", 12, 0.5);
  vertical_text(cr, p.x - 50, p.y + p.h / 2.0, "y (m)", 12);
}

// A horizontal colour bar from `lo` to `hi` under a panel, with its name and end labels.
void colour_bar(cairo_t* cr, double x, double y, const std::string& name, const std::function<Rgb(double)>& colour,
                double lo, double hi, const std::vector<std::string>& labels) {
  const int w = 180, h = 10;
  for (int i = 0; i < w; ++i) {
    const Rgb c = colour(lo + (hi - lo) * (i + 0.5) / w);
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_rectangle(cr, x + i, y, 1, h);
    cairo_fill(cr);
  }
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1);
  cairo_rectangle(cr, x - 0.5, y - 0.5, w + 1, h + 1);
  cairo_stroke(cr);
  text(cr, x, y - 5, name, 11);
  for (size_t k = 0; k < labels.size(); ++k)
    text(cr, x + w * (labels.size() > 1 ? static_cast<double>(k) / (labels.size() - 1) : 0.5), y + h + 13, labels[k], 10,
         labels.size() > 1 ? static_cast<double>(k) / (labels.size() - 1) : 0.5);
}

// Swatches with names, for a panel of categories.
void key(cairo_t* cr, double x, double y, const std::vector<std::pair<Rgb, std::string>>& entries) {
  for (const auto& [c, name] : entries) {
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_rectangle(cr, x, y, 12, 10);
    cairo_fill(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, x - 0.5, y - 0.5, 13, 11);
    cairo_stroke(cr);
    text(cr, x + 17, y + 9, name, 11);
    cairo_text_extents_t ext;
    cairo_text_extents(cr, name.c_str(), &ext);
    x += 17 + ext.x_advance + 14;
  }
}

}  // namespace

std::pair<int, int> SliceLayout::pixel(size_t p, int i, int j) const {
  const Rect& r = panels.at(p);
  if (downscale > 1) return {r.x + i / downscale, r.y + r.h - 1 - j / downscale};
  return {r.x + i * upscale + upscale / 2, r.y + r.h - 1 - j * upscale - upscale / 2};
}

SliceLayout slice_layout(const SliceImage& s) {
  const int n = s.has_truth ? 3 : 2;
  // Side by side, or stacked where that draws the cells larger (a map much wider than tall).
  Grid2 grid{n, 1};
  SliceLayout l = fit(s, grid);
  if (const SliceLayout stacked = fit(s, Grid2{1, n}); pixels_per_cell(stacked) > pixels_per_cell(l)) {
    l = stacked;
    grid = Grid2{1, n};
  }
  const int pw = l.downscale > 1 ? (s.width + l.downscale - 1) / l.downscale : s.width * l.upscale;
  const int ph = l.downscale > 1 ? (s.height + l.downscale - 1) / l.downscale : s.height * l.upscale;
  std::tie(l.width, l.height) = picture_size(grid, pw, ph);
  l.panels.clear();
  const int column = std::max(pw, kMinColumn);
  for (int k = 0; k < n; ++k)
    l.panels.push_back({kLeft + (k % grid.columns) * (column + kGapX), kTop + (k / grid.columns) * (ph + kBelow + kGapY), pw, ph});
  // The scale bar: a round length of at most 40 % of the panel (and 120 pixels).
  const double ppm = pixels_per_cell(l) / s.resolution;
  l.scale_bar_m = round_down_nice(std::min(0.4 * pw, 120.0) / ppm);
  l.scale_bar = {l.panels[0].x, l.panels[0].y + ph + 50, std::max(1, static_cast<int>(std::lround(l.scale_bar_m * ppm))), 6};
  return l;
}

void write_slice_png(const std::filesystem::path& file, const SliceImage& slice, const std::string& title) {
  const SliceLayout l = slice_layout(slice);
  const Canvas canvas = new_canvas(l.width, l.height, title + "  (z = " + fixed(slice.z, 2) + " m)", 24, 16);
  cairo_t* cr = canvas.cr();
  const auto score_rank = [&](size_t k) { return slice.mean[k]; };
  auto panel = [&](size_t index, const std::string& name, const std::function<Rgb(size_t)>& colour,
                   const std::function<double(size_t)>& rank) {
    const SliceLayout::Rect& p = l.panels[index];
    const SurfacePtr image = panel_image(slice, l, colour, rank);
    cairo_save(cr);
    cairo_translate(cr, p.x, p.y);
    if (l.downscale == 1) cairo_scale(cr, l.upscale, l.upscale);
    cairo_set_source_surface(cr, image.get(), 0, 0);
    cairo_pattern_set_filter(cairo_get_source(cr), CAIRO_FILTER_NEAREST);
    cairo_paint(cr);
    cairo_restore(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    cairo_set_line_width(cr, 1);
    cairo_rectangle(cr, p.x - 0.5, p.y - 0.5, p.w + 1, p.h + 1);
    cairo_stroke(cr);
    text(cr, p.x + p.w / 2.0, p.y - 9, name, 13, 0.5);
    draw_metre_axes(cr, slice, l, p);
  };
  const auto legend_y = [&](size_t index) { return l.panels[index].y + l.panels[index].h + 50.0; };

  panel(0, "occupancy probability", [&](size_t k) { return score_colour(slice.mean[k]); }, score_rank);
  colour_bar(cr, l.panels[0].x + 150.0, legend_y(0), "probability (grey: no evidence)", score_colour, 0, 1,
             {"0 free", "0.5", "1 occupied"});
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_rectangle(cr, l.scale_bar.x, l.scale_bar.y, l.scale_bar.w, l.scale_bar.h);
  cairo_fill(cr);
  text(cr, l.scale_bar.x + l.scale_bar.w / 2.0, l.scale_bar.y + 20, tick_text(l.scale_bar_m) + " m", 11, 0.5);

  if (slice.has_variance) {
    panel(1, "posterior variance", [&](size_t k) { return variance_colour(slice.variance[k]); }, score_rank);
    colour_bar(cr, l.panels[1].x, legend_y(1), "variance of the Beta posterior", variance_colour, 0, 0.25,
               {"0", "0.125", "0.25"});
  } else {
    // No variance in this format (an OctoMap tree): show where the map has evidence instead.
    panel(1, "evidence (no variance in this format)",
          [&](size_t k) { return slice.evidence[k] ? kEvidence : kNoEvidence; },
          [&](size_t k) { return slice.evidence[k] + slice.mean[k]; });
    key(cr, l.panels[1].x, legend_y(1), {{kEvidence, "evidence"}, {kNoEvidence, "none"}});
  }
  if (slice.has_truth) {
    const auto truth_rank = [&](size_t k) {
      return slice.truth[k] == TruthLabel::kOccupied ? 2.0 : slice.truth[k] == TruthLabel::kFree ? 1.0 : 0.0;
    };
    panel(2, "truth",
          [&](size_t k) {
            return slice.truth[k] == TruthLabel::kOccupied ? kTruthOccupied
                   : slice.truth[k] == TruthLabel::kFree   ? kTruthFree
                                                           : kTruthOutside;
          },
          truth_rank);
    key(cr, l.panels[2].x, legend_y(2),
        {{kTruthOccupied, "occupied"}, {kTruthFree, "free"}, {kTruthOutside, "outside the truth"}});
  }
  write_png(file, canvas.surface.get());
}

}  // namespace bgkmap::eval
