// bgkmap diff: what changed between two native maps of one grid -- the cells that went occupied
// -> free and free -> occupied, as a point cloud (.ply), an OctoMap tree (.ot) or a picture (.png).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/eval/plot.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/map_changes.hpp"
#include "cli/commands.hpp"
#include "cli/output_names.hpp"

namespace bgkmap::cli {

namespace {

struct DiffRequest {
  std::string a, b;
  std::vector<std::string> outputs;
  std::string json;
  std::optional<float> occupied_threshold, free_threshold;
  double z = NAN;
  bool quiet = false;
};

// The layer (z index) holding the most changed cells; of equal counts the lowest.
int32_t busiest_change_layer(const MapChanges& changes) {
  std::map<int32_t, size_t> per_layer;
  for (const auto* list : {&changes.cleared, &changes.appeared})
    for (const CellChange& c : *list) ++per_layer[c.index.z];
  int32_t best = 0;
  size_t most = 0;
  for (const auto& [z, n] : per_layer)
    if (n > most) best = z, most = n;
  return best;
}

// Changed cells of one layer as a slice: B's probability where a cell changed (black: appeared,
// white: cleared), no evidence elsewhere.
eval::SliceImage change_slice(const MapChanges& changes, int32_t layer) {
  const double r = changes.resolution_m;
  eval::SliceImage s;
  s.resolution = r;
  s.z = (layer + 0.5) * r;
  int32_t x0 = INT32_MAX, y0 = INT32_MAX, x1 = INT32_MIN, y1 = INT32_MIN;
  for (const auto* list : {&changes.cleared, &changes.appeared})
    for (const CellChange& c : *list) {
      x0 = std::min(x0, c.index.x), y0 = std::min(y0, c.index.y);
      x1 = std::max(x1, c.index.x), y1 = std::max(y1, c.index.y);
    }
  s.x0 = x0 - 1, s.y0 = y0 - 1;
  s.width = x1 - x0 + 3, s.height = y1 - y0 + 3;
  s.box = {{s.x0 * r, s.y0 * r, layer * r}, {(s.x0 + s.width) * r, (s.y0 + s.height) * r, (layer + 1) * r}};
  const size_t n = static_cast<size_t>(s.width) * s.height;
  s.mean.assign(n, eval::kUnknownScore);
  s.evidence.assign(n, 0);
  s.truth.assign(n, eval::TruthLabel::kUnknown);
  for (const auto* list : {&changes.cleared, &changes.appeared})
    for (const CellChange& c : *list) {
      if (c.index.z != layer) continue;
      const size_t i = static_cast<size_t>(c.index.y - s.y0) * s.width + (c.index.x - s.x0);
      s.mean[i] = c.probability_b;
      s.evidence[i] = 1;
    }
  return s;
}

void write_output(const std::string& out, const MapChanges& changes, const DiffRequest& req) {
  const std::string ext = std::filesystem::path(out).extension().string();
  if (ext == ".ply") return write_changes_ply(out, changes);
  if (ext == ".ot") return write_changes_ot(out, changes);
  if (changes.cleared.empty() && changes.appeared.empty())
    throw std::runtime_error(out + ": no cell changed, so there is no picture to draw");
  const int32_t layer = std::isnan(req.z) ? busiest_change_layer(changes)
                                          : static_cast<int32_t>(std::floor(req.z / changes.resolution_m));
  eval::write_slice_png(out, change_slice(changes, layer),
                        std::filesystem::path(req.a).filename().string() + " -> " +
                            std::filesystem::path(req.b).filename().string() +
                            ": black free -> occupied, white occupied -> free");
}

nlohmann::json cells_json(const std::vector<CellChange>& list) {
  nlohmann::json cells = nlohmann::json::array();
  for (const CellChange& c : list)
    cells.push_back({{"cell", {c.index.x, c.index.y, c.index.z}}, {"probability_a", c.probability_a},
                     {"probability_b", c.probability_b}});
  return cells;
}

void run_diff(const DiffRequest& req) {
  if (req.occupied_threshold && req.free_threshold && *req.free_threshold > *req.occupied_threshold)
    throw std::invalid_argument("--free-threshold must not be above --occupied-threshold");
  for (const std::string& out : req.outputs) check_output_path(out);
  if (!req.json.empty()) check_output_path(req.json);
  const NativeMapFile a = read_native_map_or_shards(req.a);
  const NativeMapFile b = read_native_map_or_shards(req.b);
  MapChanges changes;
  try {
    changes = compare_maps(a.map, b.map, req.occupied_threshold, req.free_threshold);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(req.a + " and " + req.b + ": " + e.what());
  }
  OutputBatch batch;
  for (const std::string& out : req.outputs) write_output(out, changes, req);
  if (!req.json.empty()) {
    const nlohmann::json report = {{"a", req.a},
                                   {"b", req.b},
                                   {"resolution", changes.resolution_m},
                                   {"compared_cells", changes.compared},
                                   {"occupied_to_free", changes.cleared.size()},
                                   {"free_to_occupied", changes.appeared.size()},
                                   {"cleared", cells_json(changes.cleared)},
                                   {"appeared", cells_json(changes.appeared)}};
    write_file_atomically(req.json, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
  }
  batch.commit();
  if (!req.quiet)
    std::printf("%zu cells occupied -> free, %zu free -> occupied, of %llu cells with evidence in both maps\n",
                changes.cleared.size(), changes.appeared.size(), static_cast<unsigned long long>(changes.compared));
}

}  // namespace

void add_diff_command(CLI::App& app) {
  auto req = std::make_shared<DiffRequest>();
  CLI::App* cmd = app.add_subcommand(
      "diff", "Cells that changed between two native maps of one grid: occupied -> free and free -> occupied, "
              "with both probabilities (a cell either map calls unknown is no change)");
  cmd->add_option("a", req->a, "The earlier map (.bgk, or the shards of a distributed build)")->required();
  cmd->add_option("b", req->b, "The later map, of the same resolution, block depth and (planar) layer")->required();
  cmd->add_option("-o,--output", req->outputs,
                  "Output (repeat -o for several) by extension: .ply (the changed cells' centres with fields "
                  "probability_a, probability_b and change: +1 free -> occupied, -1 occupied -> free), .ot (an "
                  "OctoMap tree of the changed cells at B's probability), .png (a horizontal slice of them)")
      ->check(output_extension({".ply", ".ot", ".png"}, "diff writes .ply, .ot or .png"));
  cmd->add_option("--json", req->json, "Write the summary and every changed cell (index, both probabilities) here");
  cmd->add_option("--occupied-threshold", req->occupied_threshold,
                  "Mean above which a cell is occupied, in both maps (default: each map's own)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--free-threshold", req->free_threshold,
                  "Mean below which a cell is free, in both maps (default: each map's own)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--z", req->z, "Height (m) of the .png's slice; default the layer with the most changed cells");
  cmd->add_flag("-q,--quiet", req->quiet, "No summary line");
  cmd->callback([req] { run_diff(*req); });
}

}  // namespace bgkmap::cli
