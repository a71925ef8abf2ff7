// bgkmap render: a map of any method (.bgk, .ot, .bt) drawn as a PNG on a horizontal plane:
// occupancy probability and posterior variance (or, for trees, where there is evidence). By
// default the layer with the most occupied cells: a building's walls, a planar laser's scan plane.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bgkmap/eval/plot.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "cli/commands.hpp"
#include "cli/finite_number.hpp"
#include "cli/output_names.hpp"

namespace bgkmap::cli {

namespace {

struct RenderRequest {
  std::string map;
  std::string output;
  std::string title;
  double z = NAN;
};

void run_render(const RenderRequest& req) {
  check_output_path(req.output);
  const std::unique_ptr<eval::ScoredMap> map = eval::load_scored_map(req.map);
  const sim::Box3d bounds = map->observed_bounds();
  if (bounds.min.x > bounds.max.x) throw InputError(req.map, "the map has no cell with evidence");
  const std::optional<double> busiest = std::isnan(req.z) ? eval::busiest_layer_z(*map) : std::nullopt;
  const double z = !std::isnan(req.z) ? req.z : busiest ? *busiest : 0.5 * (bounds.min.z + bounds.max.z);
  const eval::SliceImage slice = eval::make_slice(*map, nullptr, bounds, z);
  eval::write_slice_png(req.output, slice,
                        req.title.empty() ? std::filesystem::path(req.map).filename().string() : req.title);
  const eval::SliceLayout layout = eval::slice_layout(slice);
  const std::string why = !std::isnan(req.z) ? "" : busiest ? " (the default layer: see --help)" : " (no occupied cell: the middle height)";
  const std::string cells_per_pixel =
      layout.downscale > 1 ? std::to_string(layout.downscale) + "x" + std::to_string(layout.downscale) + " cells a pixel" : std::to_string(layout.upscale) + " px a cell";
  std::fprintf(stderr, "bgkmap: %d x %d cells at z = %.3f m%s, %d x %d px (%s) -> %s\n", slice.width, slice.height, z,
               why.c_str(), layout.width, layout.height, cells_per_pixel.c_str(), req.output.c_str());
}

}  // namespace

void add_render_command(CLI::App& app) {
  auto req = std::make_shared<RenderRequest>();
  CLI::App* cmd = app.add_subcommand(
      "render",
      "Draw a map (.bgk, .ot, .bt) on a horizontal plane as a PNG: occupancy probability and variance, axes in metres, a scale bar, colour bars; at most 2000 px a side (a larger map is drawn several cells a pixel, each pixel its most occupied cell)");
  cmd->add_option("map", req->map, "Map of any method: .bgk, .ot or .bt")->required();
  cmd->add_option("-o,--output", req->output, "PNG to write")
      ->required()
      ->check(output_extension({".png"}, "render writes a PNG image"));
  cmd->add_option("--z", req->z,
                  "Height of the plane (m); default the layer with the most wall cells: occupied, with occupied cells above and below and a seen, unoccupied cell beside (walls, not a floor or ceiling); a planar map: its layer with the most occupied cells; no occupied cell: the middle of the cells with evidence")
      ->check(finite_number("--z", "height", "METRES"));
  cmd->add_option("--title", req->title, "Title of the figure (default: the map's file name)");
  cmd->callback([req] { run_render(*req); });
}

}  // namespace bgkmap::cli
