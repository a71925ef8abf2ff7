#include "bgkmap/viz/viewer.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <ostream>
#include <string>
#include <tuple>
#include <vector>

#include <nlohmann/json.hpp>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "viz/view_page.hpp"

namespace bgkmap::viz {

namespace {

std::string base64(const std::vector<uint8_t>& bytes) {
  static const char* const table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  size_t i = 0;
  for (; i + 2 < bytes.size(); i += 3) {
    const uint32_t v = (uint32_t(bytes[i]) << 16) | (uint32_t(bytes[i + 1]) << 8) | bytes[i + 2];
    out += {table[v >> 18], table[(v >> 12) & 63], table[(v >> 6) & 63], table[v & 63]};
  }
  if (i + 1 == bytes.size()) {
    const uint32_t v = uint32_t(bytes[i]) << 16;
    out += {table[v >> 18], table[(v >> 12) & 63], '=', '='};
  } else if (i + 2 == bytes.size()) {
    const uint32_t v = (uint32_t(bytes[i]) << 16) | (uint32_t(bytes[i + 1]) << 8);
    out += {table[v >> 18], table[(v >> 12) & 63], table[(v >> 6) & 63], '='};
  }
  return out;
}

// The map's cells in a corner-to-corner box at the finest level, for the page's 16-bit offsets.
struct Extent {
  int64_t lo[3], hi[3];
};

Extent extent_of(const std::vector<ViewCell>& cells) {
  Extent e;
  for (int k = 0; k < 3; ++k) {
    e.lo[k] = std::numeric_limits<int64_t>::max();
    e.hi[k] = std::numeric_limits<int64_t>::min();
  }
  for (const ViewCell& c : cells) {
    const int64_t v[3] = {c.x, c.y, c.z};
    for (int k = 0; k < 3; ++k) {
      const int64_t size = int64_t{1} << c.level;  // v * 2^level: shifting a negative v is undefined
      e.lo[k] = std::min(e.lo[k], v[k] * size);
      e.hi[k] = std::max(e.hi[k], (v[k] + 1) * size);
    }
  }
  return e;
}

}  // namespace

int merge_to_cap(ViewMap& map, size_t max_cells) {
  int level = 0;
  std::vector<ViewCell>& cells = map.cells;
  while (cells.size() > max_cells && level < 24) {
    ++level;
    for (ViewCell& c : cells) {
      if (c.level >= level) continue;
      const int shift = level - c.level;
      c.x >>= shift;  // arithmetic shift: floor division for negative indices too
      c.y >>= shift;
      c.z >>= shift;
      c.level = static_cast<uint8_t>(level);
    }
    std::sort(cells.begin(), cells.end(), [](const ViewCell& a, const ViewCell& b) {
      return std::tie(a.level, a.x, a.y, a.z) < std::tie(b.level, b.x, b.y, b.z);
    });
    size_t out = 0;
    for (size_t i = 0; i < cells.size();) {
      ViewCell merged = cells[i];
      size_t j = i + 1;
      for (; j < cells.size() && cells[j].level == merged.level && cells[j].x == merged.x && cells[j].y == merged.y &&
             cells[j].z == merged.z;
           ++j) {
        merged.probability = std::max(merged.probability, cells[j].probability);
        merged.uncertain = merged.uncertain && cells[j].uncertain;
        merged.occupied = merged.occupied || cells[j].occupied;
      }
      cells[out++] = merged;
      i = j;
    }
    cells.resize(out);
  }
  return level;
}

ViewReduction fit_to_cap(ViewMap& map, size_t max_cells) {
  ViewReduction r;
  std::vector<ViewCell>& cells = map.cells;
  if (cells.size() <= max_cells) return r;
  const auto others = std::stable_partition(cells.begin(), cells.end(), [](const ViewCell& c) { return c.occupied; });
  const size_t occupied = static_cast<size_t>(others - cells.begin());
  if (occupied > max_cells) {
    cells.erase(others, cells.end());
    r.level = merge_to_cap(map, max_cells);
    r.min_probability = map.occupied_threshold;
    return r;
  }
  std::sort(others, cells.end(), [](const ViewCell& a, const ViewCell& b) { return a.probability > b.probability; });
  // The first left out sets the bound; the kept ones of the same probability go too.
  size_t keep = max_cells;
  const float bound = cells[keep].probability;
  while (keep > occupied && cells[keep - 1].probability == bound) --keep;
  cells.resize(keep);
  r.min_probability = std::nextafter(bound, 2.0f);
  return r;
}

ViewStats write_view_html(const std::filesystem::path& file, ViewMap map, size_t max_cells) {
  if (max_cells < kMinViewCap) throw std::invalid_argument("the cap on boxes must be at least 8");
  ViewStats stats;
  stats.map_cells = map.cells.size();
  const size_t map_occupied =
      static_cast<size_t>(std::count_if(map.cells.begin(), map.cells.end(), [](const ViewCell& c) { return c.occupied; }));
  stats.reduction = fit_to_cap(map, max_cells);
  stats.cells = map.cells.size();
  const int level = stats.reduction.level;
  const Extent e = map.cells.empty() ? Extent{{0, 0, 0}, {1, 1, 1}} : extent_of(map.cells);
  // Offsets at the coarsest level present keep within 16 bits where the finest would not.
  for (int k = 0; k < 3; ++k)
    if (((e.hi[k] - e.lo[k]) >> level) > 65535)
      throw InputError(file, "the map spans " + std::to_string(e.hi[k] - e.lo[k]) +
                                 " cells on one axis: more than the viewer's 65,535 (raise the resolution of the map)");

  // Per box: x, y, z offsets from the lowest corner in units of 2^level cells (uint16 each), then
  // level, probability (0..255) and flags (1: uncertain, 2: occupied by the map's thresholds).
  std::vector<uint8_t> positions, info;
  positions.reserve(map.cells.size() * 6);
  info.reserve(map.cells.size() * 3);
  for (const ViewCell& c : map.cells) {
    const int64_t v[3] = {c.x, c.y, c.z};
    for (int k = 0; k < 3; ++k) {
      const uint16_t offset = static_cast<uint16_t>(v[k] - (e.lo[k] >> c.level));
      positions.push_back(static_cast<uint8_t>(offset & 0xff));
      positions.push_back(static_cast<uint8_t>(offset >> 8));
    }
    info.push_back(c.level);
    info.push_back(static_cast<uint8_t>(std::clamp(c.probability, 0.0f, 1.0f) * 255.0f + 0.5f));
    info.push_back(static_cast<uint8_t>((c.uncertain ? 1 : 0) | (c.occupied ? 2 : 0)));
  }
  const nlohmann::json meta = {
      {"source", map.source},
      {"resolution", map.resolution_m},
      {"origin", {e.lo[0], e.lo[1], e.lo[2]}},
      {"extent", {e.hi[0] - e.lo[0], e.hi[1] - e.lo[1], e.hi[2] - e.lo[2]}},
      {"cells", map.cells.size()},
      {"map_cells", stats.map_cells},
      {"map_occupied", map_occupied},
      {"level", level},
      {"max_cells", max_cells},
      {"occupied_threshold", map.occupied_threshold},
      {"min_probability", stats.reduction.min_probability},
      {"has_variance", map.has_variance},
  };
  const std::string page = view_page(meta.dump(), base64(positions), base64(info));
  write_file_atomically(file, [&](std::ostream& out) { out << page; });
  stats.bytes = page.size();
  return stats;
}

}  // namespace bgkmap::viz
