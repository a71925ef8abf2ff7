// bgkmap info: what a native map holds.
#include <algorithm>
#include <cstdio>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/map_io.hpp"
#include "cli/commands.hpp"
#include "core/number_text.hpp"

namespace bgkmap::cli {

namespace {

struct InfoRequest {
  std::string map_file;
  bool json = false;
};

// Every fraction as its decimal: cell centres are sums of products of the resolution.
void round_to_decimals(nlohmann::json& j) {
  if (j.is_number_float()) j = decimal_value(j.get<double>());
  if (j.is_structured())
    for (nlohmann::json& item : j) round_to_decimals(item);
}

nlohmann::json map_summary(const BgkMap& map) {
  const Grid& grid = map.grid();
  size_t occupied = 0, free_cells = 0, unknown_with_evidence = 0, evidence = 0;
  double lo[3] = {std::numeric_limits<double>::max(), std::numeric_limits<double>::max(), std::numeric_limits<double>::max()};
  double hi[3] = {-lo[0], -lo[1], -lo[2]};
  map.for_each_cell_with_evidence([&](const CellIndex& cell, const CellPosterior& p) {
    ++evidence;
    switch (p.state(map.params().classify)) {
      case CellState::kOccupied: ++occupied; break;
      case CellState::kFree: ++free_cells; break;
      case CellState::kUnknown: ++unknown_with_evidence; break;
    }
    const Vec3d c = grid.cell_center_d(cell);
    const double v[3] = {c.x, c.y, c.z};
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], v[k]);
      hi[k] = std::max(hi[k], v[k]);
    }
  });
  nlohmann::json bounds = nullptr;
  if (evidence > 0) bounds = {{"min", {lo[0], lo[1], lo[2]}}, {"max", {hi[0], hi[1], hi[2]}}};
  return {{"params", params_to_json(map.params())},
          {"blocks", map.block_count()},
          {"cells", map.block_count() * static_cast<size_t>(map.cells_per_block())},
          {"cells_with_evidence", evidence},
          {"occupied", occupied},
          {"free", free_cells},
          {"unknown_with_evidence", unknown_with_evidence},
          {"evidence_cell_centre_bounds", bounds}};
}

void run_info(const InfoRequest& req) {
  const NativeMapFile file = read_native_map_or_shards(req.map_file);
  nlohmann::json summary = map_summary(file.map);
  summary["format_version"] = file.version;
  summary["method"] = file.method;
  nlohmann::json held = nlohmann::json::array();
  uint64_t held_scans = 0;
  for (const HeldInput& h : file.held) {
    held.push_back({{"path", h.path}, {"sha256", h.sha256}, {"scans", h.scans}});
    held_scans += h.scans;
  }
  summary["held_inputs"] = held;
  round_to_decimals(summary);
  if (req.json) {
    std::printf("%s\n", summary.dump(2).c_str());
    return;
  }
  std::printf("map: %s (--method %s)\n", req.map_file.c_str(), file.method.c_str());
  for (const auto& item : summary["params"].items())
    std::printf("  %-20s %s\n", item.key().c_str(), item.value().dump().c_str());
  for (const char* key : {"format_version", "blocks", "cells", "cells_with_evidence", "occupied", "free", "unknown_with_evidence"})
    std::printf("%-22s %s\n", key, summary[key].dump().c_str());
  std::printf("%-22s %llu scans of %zu files (--resume passes over them)\n", "held inputs",
              static_cast<unsigned long long>(held_scans), file.held.size());
  if (!summary["evidence_cell_centre_bounds"].is_null())
    std::printf("%-22s %s .. %s\n", "bounds (cell centres)", summary["evidence_cell_centre_bounds"]["min"].dump().c_str(),
                summary["evidence_cell_centre_bounds"]["max"].dump().c_str());
}

}  // namespace

void add_info_command(CLI::App& app) {
  auto req = std::make_shared<InfoRequest>();
  CLI::App* cmd = app.add_subcommand("info", "Print a native map's parameters and counts");
  cmd->add_option("map", req->map_file, "Native .bgk map, or the shard folder of a distributed build")->required();
  cmd->add_flag("--json", req->json, "Print JSON instead of text");
  cmd->callback([req] { run_info(*req); });
}

}  // namespace bgkmap::cli
