// bgkmap view: a map as one self-contained HTML page with a 3-D WebGL view of its occupied cells.
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/viz/viewer.hpp"
#include "cli/commands.hpp"
#include "cli/output_names.hpp"

namespace bgkmap::cli {

namespace {

struct ViewRequest {
  std::string map;
  std::string output;
  size_t max_cells = viz::kDefaultMaxViewCells;
  bool quiet = false;
};

std::string format_probability(float p) {
  char text[16];
  std::snprintf(text, sizeof text, "%.3f", p);
  return text;
}

void run_view(const ViewRequest& req) {
  check_output_path(req.output);
  if (req.max_cells < viz::kMinViewCap) throw std::invalid_argument("--max-cells must be at least 8");
  const viz::ViewStats stats = viz::write_view_html(req.output, viz::read_view_map(req.map), req.max_cells);
  if (req.quiet) return;
  std::string fitted;
  if (stats.reduction.level > 0)
    fitted = ", occupied cells merged " + std::to_string(1 << stats.reduction.level) + "x per side to fit --max-cells";
  else if (stats.cells < stats.map_cells)
    fitted = ", those of probability under " + format_probability(stats.reduction.min_probability) +
             " left out to fit --max-cells";
  std::fprintf(stderr, "bgkmap: %s: %zu boxes for the map's %zu cells of probability >= 0.5%s, %.1f MB\n", req.output.c_str(),
               stats.cells, stats.map_cells, fitted.c_str(), stats.bytes / 1e6);
}

}  // namespace

void add_view_command(CLI::App& app) {
  auto req = std::make_shared<ViewRequest>();
  CLI::App* cmd = app.add_subcommand(
      "view", "Write a map's occupied cells as one self-contained HTML page with a 3-D view (WebGL; no server or network): a ground grid, axes, a legend, a height clip (open PAGE.html#clip=Z to start clipped above Z m); a planar map starts from above");
  cmd->add_option("map", req->map, "Map: .bgk, .ot or .bt")->required();
  cmd->add_option("-o,--output", req->output, "HTML file to write")
      ->required()
      ->check(view_output_extension());
  cmd->add_option("--max-cells", req->max_cells,
                  "Most boxes in the page (at least 8). Above it the page keeps the occupied cells and the most probable of the others; if the occupied cells alone are more, they are merged into their 2x2x2 parents (keeping the highest probability) until under")
      ->capture_default_str();
  cmd->add_flag("-q,--quiet", req->quiet, "No summary line");
  cmd->callback([req] { run_view(*req); });
}

}  // namespace bgkmap::cli
