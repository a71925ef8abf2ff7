// bgkmap export: a native map out to a navigation stack, by extension: a ROS map_server
// occupancy grid (.pgm + .yaml) and clouds of occupied cells (.ply, .pcd).
#include <cmath>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/map_export.hpp"
#include "bgkmap/io/map_io.hpp"
#include "cli/commands.hpp"
#include "cli/output_names.hpp"

namespace bgkmap::cli {

namespace {

struct ExportRequest {
  std::string map;
  std::vector<std::string> outputs;
  double z_min = NAN, z_max = NAN;
};

HeightBand band_of(const ExportRequest& req) {
  if (std::isnan(req.z_min) != std::isnan(req.z_max))
    throw std::invalid_argument("--z-min and --z-max go together (a height band; without both, every height)");
  if (std::isnan(req.z_min)) return {};
  return height_band_between(req.z_min, req.z_max);
}

void run_export(const ExportRequest& req) {
  const HeightBand band = band_of(req);
  for (const std::string& out : req.outputs) check_map_output(out);
  const NativeMapFile file = read_native_map_or_shards(req.map);
  const ExportCells cells = export_cells(file.map);
  OutputBatch batch;
  for (const std::string& out : req.outputs) write_map_export(out, cells, band);
  batch.commit();
  for (const std::string& out : req.outputs) std::fprintf(stderr, "bgkmap: wrote %s\n", out.c_str());
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto req = std::make_shared<ExportRequest>();
  CLI::App* cmd = app.add_subcommand(
      "export", "Export a native map for a navigation stack: ROS map_server .pgm + .yaml, occupied cells as .ply/.pcd");
  cmd->add_option("map", req->map, "Native map (.bgk) or the shards of a distributed build")->required();
  cmd->add_option("-o,--output", req->outputs,
                  "Output (repeat -o for several) by extension: .pgm (a ROS map_server trinary occupancy grid, its .yaml written beside it; a "
                  "3-D map projected over the height band), .ply or .pcd (every occupied cell's centre with fields "
                  "probability and variance)")
      ->required()
      ->check(export_output_extension());
  cmd->add_option("--z-min", req->z_min,
                  "With --z-max, the height band a 3-D map's .pgm projects (m; cells whose centre lies in it): a "
                  "column is occupied if any cell in the band is, free if none is and one is free, else unknown. "
                  "Default: every height (a max-projection). Refused for a planar (--2d) map");
  cmd->add_option("--z-max", req->z_max, "Top of the height band (m), with --z-min");
  cmd->callback([req] { run_export(*req); });
}

}  // namespace bgkmap::cli
