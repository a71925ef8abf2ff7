// bgkmap query: posterior of the cells holding given points; ray casts, the cells of a box and the
// occupied cells (cli/map_query_output).
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/map/map_queries.hpp"
#include "cli/commands.hpp"
#include "cli/map_query_output.hpp"
#include "cli/progress.hpp"
#include "io/text_lines.hpp"

namespace bgkmap::cli {

namespace {

struct QueryRequest {
  std::string map_file;
  std::string points = "-";
  std::string rays;                // a file of rays, or -
  std::vector<double> box;         // xmin, ymin, zmin, xmax, ymax, zmax
  bool occupied = false;
  bool include_unobserved = false;
  std::string unknown = "stop";
  ProgressFlags progress;
};

// --rays, --box, --occupied: on the whole map (a shard folder merged).
void run_map_query(const QueryRequest& req) {
  const UnknownPolicy policy = unknown_policy_from_string(req.unknown);
  std::optional<CellBox> box;
  if (!req.box.empty()) box = CellBox{{req.box[0], req.box[1], req.box[2]}, {req.box[3], req.box[4], req.box[5]}};
  try {
    if (box) check_cell_box(*box);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--box: ") + e.what());
  }
  const BgkMap map = read_native_map_or_shards(req.map_file).map;
  if (!req.rays.empty()) return print_ray_casts(map, req.rays, policy);
  const CellSelection selection = req.occupied ? CellSelection::kOccupied
                                  : req.include_unobserved ? CellSelection::kAll
                                                           : CellSelection::kWithEvidence;
  print_cells_in_box(map, box ? &*box : nullptr, selection);
}

void run_query(const QueryRequest& req) {
  std::optional<ShardedMapReader> shards;
  std::optional<BgkMap> single;
  if (is_shard_manifest(req.map_file)) shards.emplace(req.map_file);
  else single.emplace(read_native_map(req.map_file));
  // TextLines bounds a line's length and refuses binary data (a device such as /dev/zero grew
  // std::getline's line to the address-space limit).
  const std::filesystem::path source = req.points == "-" ? "/dev/stdin" : req.points;
  if (std::filesystem::is_directory(source)) throw InputError(source, "is a folder, not a points file");
  io_detail::TextLines lines(source);
  ProgressFlags flags = req.progress;
  if (::isatty(::fileno(stdout)) == 1 && !flags.force) flags.quiet = true;  // the bar would break the printed lines
  ProgressBar progress(flags);
  std::string line;
  uint64_t done = 0;
  for (; lines.next(line); ++done) {
    // The lines to come, estimated from the share of the file read (a pipe's are not known).
    const double fraction = lines.fraction_read();
    const uint64_t total = fraction > 0 ? std::max(done, static_cast<uint64_t>(std::llround(double(done) / fraction))) : 0;
    progress.report({"query", "lines", done, total, true});
    const std::vector<std::string_view> fields = io_detail::split_fields(line);
    if (fields.empty() || fields.front().front() == '#') continue;
    double x = 0, y = 0, z = 0;
    if (fields.size() < 3 || !io_detail::parse_number(fields[0], x) || !io_detail::parse_number(fields[1], y) ||
        !io_detail::parse_number(fields[2], z))
      lines.fail("expected 'x y z', got '" + io_detail::excerpt(line) + "'");
    if (!within_key_range(x, y, z))
      lines.fail("'" + io_detail::excerpt(line) + "' lies beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
    const BgkMap& map = shards ? shards->map_at(x, y, z) : *single;
    const CellPosterior post = map.query(x, y, z);
    print_cell_line(map.grid().cell_center_d(map.cell_of(x, y, z)), post, post.state(map.params().classify));
  }
  progress.report({"query", "lines", done, done, false});
  progress.finish();
}

}  // namespace

void add_query_command(CLI::App& app) {
  auto req = std::make_shared<QueryRequest>();
  CLI::App* cmd = app.add_subcommand(
      "query",
      "Print 'cx cy cz alpha beta mean variance state' for each 'x y z' line (c = centre of the cell holding it); "
      "with --rays, 'hit cx cy cz distance state stop' for each ray; with --box or --occupied, the cell line of "
      "each cell centred in the box, or occupied (docs/QUERIES.md)");
  cmd->add_option("map", req->map_file, "Native .bgk map, or the shard folder of a distributed build")->required();
  CLI::Option* points =
      cmd->add_option("--points", req->points, "File of 'x y z' lines, or - for standard input")->capture_default_str();
  CLI::Option* rays = cmd->add_option(
      "--rays", req->rays,
      "File of 'ox oy oz dx dy dz [max_range]' lines, or - for standard input: the first occupied cell along each "
      "ray (the start cell counts; max_range absent or 0: no limit). Prints 'hit cx cy cz distance state stop': "
      "hit 1/0, the centre of the cell where the ray stopped, the distance to where it enters it (to the range's "
      "end for max_range, the map's edge for map_end), its state, why it stopped "
      "(occupied, unknown, max_range, map_end). A planar map casts in its plane (z ignored)");
  CLI::Option* unknown = cmd->add_option("--unknown", req->unknown,
                                         "At an unknown cell a ray stops (as OctoMap's castRay) or passes through it "
                                         "(castRay's ignoreUnknown)")
                             ->check(CLI::IsMember({"stop", "pass"}))
                             ->capture_default_str();
  CLI::Option* box = cmd->add_option("--box", req->box,
                                     "xmin,ymin,zmin,xmax,ymax,zmax: the cells whose centres lie in this box (closed; "
                                     "a planar map ignores z), those with evidence unless --include-unobserved")
                         ->expected(6)
                         ->delimiter(',');
  CLI::Option* occupied =
      cmd->add_flag("--occupied", req->occupied, "The cells the map calls occupied (of the --box, else of the whole map)");
  CLI::Option* unobserved = cmd->add_flag("--include-unobserved", req->include_unobserved,
                                          "With --box: every cell centred in it, those never observed at the prior");
  rays->excludes(points)->excludes(box)->excludes(occupied);
  box->excludes(points);
  occupied->excludes(points);
  unknown->needs(rays);
  unobserved->needs(box)->excludes(occupied);
  add_progress_flags(*cmd, req->progress,
                     "No progress bar (of --points; drawn only while the output does not go to a terminal, or with --progress)");
  cmd->callback([req, rays, box, occupied] {
    if (rays->count() || box->count() || occupied->count()) run_map_query(*req);
    else run_query(*req);
  });
}

}  // namespace bgkmap::cli
