// bgkmap query: posterior of the cells holding given points.
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "cli/commands.hpp"

namespace bgkmap::cli {

namespace {

struct QueryRequest {
  std::string map_file;
  std::string points = "-";
};

void run_query(const QueryRequest& req) {
  std::optional<ShardedMapReader> shards;
  std::optional<BgkMap> single;
  if (is_shard_manifest(req.map_file)) shards.emplace(req.map_file);
  else single.emplace(read_native_map(req.map_file));
  std::ifstream file;
  std::istream* in = &std::cin;
  const std::string source = req.points == "-" ? "<stdin>" : req.points;
  if (req.points != "-") {
    file.open(req.points);
    if (!file) throw InputError(req.points, "cannot open points file");
    in = &file;
  }
  std::string line;
  size_t line_number = 0;
  while (std::getline(*in, line)) {
    ++line_number;
    const size_t first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    double x, y, z;
    if (!(fields >> x >> y >> z))
      throw InputError(source, "line " + std::to_string(line_number) + ": expected 'x y z', got '" + line + "'");
    if (!within_key_range(x, y, z))
      throw InputError(source, "line " + std::to_string(line_number) + ": '" + line + "' lies beyond the map's " +
                                   "key range (|x|, |y|, |z| at most 1e6 m)");
    const BgkMap& map = shards ? shards->map_at(x, y, z) : *single;
    const CellPosterior post = map.query(x, y, z);
    const Vec3d c = map.grid().cell_center_d(map.cell_of(x, y, z));
    std::printf("%.9g %.9g %.9g %.9g %.9g %.9g %.9g %s\n", c.x, c.y, c.z, post.alpha, post.beta, post.mean(),
                post.variance(), to_string(post.state(map.params().classify)));
  }
}

}  // namespace

void add_query_command(CLI::App& app) {
  auto req = std::make_shared<QueryRequest>();
  CLI::App* cmd = app.add_subcommand(
      "query", "Print 'cx cy cz alpha beta mean variance state' for each 'x y z' line (c = centre of the cell holding it)");
  cmd->add_option("map", req->map_file, "Native .bgk map, or the shard folder of a distributed build")->required();
  cmd->add_option("--points", req->points, "File of 'x y z' lines, or - for standard input")->capture_default_str();
  cmd->callback([req] { run_query(*req); });
}

}  // namespace bgkmap::cli
