// The .bgk side of ScoredMap and the choice of reader by extension; the OctoMap trees are in
// octree_scored_map.cpp.
#include "bgkmap/eval/scored_map.hpp"

#include <utility>

#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "eval/octree_scored_map.hpp"

namespace bgkmap::eval {

namespace {

class BgkScoredMap final : public ScoredMap {
 public:
  explicit BgkScoredMap(BgkMap map) : ScoredMap(map.grid().resolution()), map_(std::move(map)) {}

  sim::Box3d observed_bounds() const override {
    sim::Box3d box = sim::Box3d::empty();
    const double r = map_.grid().resolution();
    map_.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior&) {
      box.expand(Vec3d{c.x * r, c.y * r, c.z * r});
      box.expand(Vec3d{(c.x + 1) * r, (c.y + 1) * r, (c.z + 1) * r});
    });
    return box;
  }

  MapSample sample(double x, double y, double z) const override {
    const CellPosterior p = map_.query(x, y, z);
    MapSample s;
    s.has_evidence = p.has_evidence;
    if (p.has_evidence) s.score = p.mean();
    s.variance = p.variance();
    return s;
  }

  bool has_variance() const override { return true; }
  double occupied_threshold() const override { return map_.params().classify.occupied_threshold; }
  double free_threshold() const override { return map_.params().classify.free_threshold; }

  std::vector<CellIndex> occupied_cells() const override {
    std::vector<CellIndex> cells;
    const double threshold = occupied_threshold();
    map_.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) {
      if (p.mean() > threshold) cells.push_back(c);
    });
    return cells;
  }

 private:
  BgkMap map_;
};

}  // namespace

ScoredMap::ScoredMap(double resolution) : grid_([resolution] {
  GridParams params;
  params.resolution_m = resolution;
  return params;
}()) {}

std::unique_ptr<ScoredMap> make_scored_map(BgkMap map) { return std::make_unique<BgkScoredMap>(std::move(map)); }

std::unique_ptr<ScoredMap> load_scored_map(const std::filesystem::path& file) {
  if (is_shard_manifest(file)) return make_scored_map(read_native_map_or_shards(file).map);
  const MapFormat format = readable_map_format_from_path(file);
  if (!std::filesystem::is_regular_file(file)) throw InputError(file, "map file not found");
  switch (format) {
    case MapFormat::kNative: return make_scored_map(read_native_map(file));
    case MapFormat::kOctomapTree: return load_octree_scored_map(file, /*binary=*/false);
    case MapFormat::kOctomapBinary: return load_octree_scored_map(file, /*binary=*/true);
    case MapFormat::kRosMap:
    case MapFormat::kPlyCloud:
    case MapFormat::kPcdCloud: break;  // refused above
  }
  throw InputError(file, "unknown map format");
}

MapSample sample_of_probability(std::optional<double> probability) {
  MapSample s;
  s.has_evidence = probability.has_value();
  if (probability) s.score = *probability;
  return s;
}

}  // namespace bgkmap::eval
