#include "bgkmap/io/map_changes.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <string>

#include "bgkmap/io/atomic_file.hpp"
#include "io/octomap_tree_write.hpp"

namespace bgkmap {

namespace {

void check_same_grid(const BgkMap& a, const BgkMap& b) {
  const BuildParams &pa = a.params(), &pb = b.params();
  if (pa.grid.resolution_m != pb.grid.resolution_m)
    throw std::invalid_argument("the maps' resolutions differ (" + std::to_string(pa.grid.resolution_m) + " m and " +
                                std::to_string(pb.grid.resolution_m) + " m): diff compares maps of one grid");
  if (pa.grid.block_depth != pb.grid.block_depth)
    throw std::invalid_argument("the maps' block depths differ (" + std::to_string(pa.grid.block_depth) + " and " +
                                std::to_string(pb.grid.block_depth) + "): diff compares maps of one grid");
  if (pa.preprocess.planar != pb.preprocess.planar)
    throw std::invalid_argument("one map is planar (--2d) and the other 3-D: diff compares maps of one grid");
  if (pa.preprocess.planar && pa.planar_layer() != pb.planar_layer())
    throw std::invalid_argument("the planar maps lie in different layers (--plane-z): diff compares maps of one grid");
}

ClassifyParams thresholds(const BgkMap& map, std::optional<float> occupied, std::optional<float> free) {
  ClassifyParams c = map.params().classify;
  if (occupied) c.occupied_threshold = *occupied;
  if (free) c.free_threshold = *free;
  return c;
}

bool before(const CellChange& l, const CellChange& r) {
  const CellIndex &a = l.index, &b = r.index;
  return a.z != b.z ? a.z < b.z : (a.y != b.y ? a.y < b.y : a.x < b.x);
}

void put_le32(std::string& bytes, uint32_t bits) {
  for (int b = 0; b < 4; ++b) bytes.push_back(static_cast<char>((bits >> (8 * b)) & 0xFF));
}
void put_float(std::string& bytes, double v) {
  const float f = static_cast<float>(v);
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  put_le32(bytes, bits);
}

}  // namespace

MapChanges compare_maps(const BgkMap& a, const BgkMap& b, std::optional<float> occupied_threshold,
                        std::optional<float> free_threshold) {
  check_same_grid(a, b);
  const ClassifyParams ca = thresholds(a, occupied_threshold, free_threshold);
  const ClassifyParams cb = thresholds(b, occupied_threshold, free_threshold);
  MapChanges changes;
  changes.resolution_m = a.grid().resolution();
  a.for_each_cell_with_evidence([&](const CellIndex& index, const CellPosterior& pa) {
    const Vec3d centre = a.grid().cell_center_d(index);
    const CellPosterior pb = b.query(centre.x, centre.y, centre.z);
    if (!pb.has_evidence) return;
    ++changes.compared;
    const CellState sa = pa.state(ca), sb = pb.state(cb);
    const CellChange change{index, pa.mean(), pb.mean()};
    if (sa == CellState::kOccupied && sb == CellState::kFree) changes.cleared.push_back(change);
    if (sa == CellState::kFree && sb == CellState::kOccupied) changes.appeared.push_back(change);
  });
  std::sort(changes.cleared.begin(), changes.cleared.end(), before);
  std::sort(changes.appeared.begin(), changes.appeared.end(), before);
  return changes;
}

void write_changes_ply(const std::filesystem::path& file, const MapChanges& changes) {
  std::string bytes;
  const double r = changes.resolution_m;
  for (const auto* list : {&changes.cleared, &changes.appeared})
    for (const CellChange& c : *list) {
      for (const double v : {(c.index.x + 0.5) * r, (c.index.y + 0.5) * r, (c.index.z + 0.5) * r, c.probability_a,
                             c.probability_b})
        put_float(bytes, v);
      put_le32(bytes, list == &changes.appeared ? 1u : static_cast<uint32_t>(-1));
    }
  write_file_atomically(file, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "comment bgkmap diff: cells occupied in A and free in B (change -1) or free in A and occupied in B (+1); "
           "centre (m), P(occupied) in A and in B\n"
        << "element vertex " << changes.cleared.size() + changes.appeared.size() << "\n"
        << "property float x\nproperty float y\nproperty float z\nproperty float probability_a\n"
        << "property float probability_b\nproperty int change\nend_header\n";
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  });
}

void write_changes_ot(const std::filesystem::path& file, const MapChanges& changes) {
  octomap::OcTree tree(changes.resolution_m);
  const double r = changes.resolution_m;
  for (const auto* list : {&changes.cleared, &changes.appeared})
    for (const CellChange& c : *list) {
      const double p = std::clamp(c.probability_b, 1e-6, 1 - 1e-6);
      tree.setNodeValue(octomap::point3d((c.index.x + 0.5) * r, (c.index.y + 0.5) * r, (c.index.z + 0.5) * r),
                        static_cast<float>(std::log(p / (1 - p))));
    }
  write_tree_atomically(file, tree, false);
}

}  // namespace bgkmap
