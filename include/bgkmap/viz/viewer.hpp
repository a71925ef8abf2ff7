// `bgkmap view`: a map as one self-contained HTML page (plain WebGL 2, no server, no network)
// showing its occupied cells in 3-D, with orbit controls, colour by height or probability, a
// probability threshold, a toggle for uncertain cells and a cap on the cells drawn.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace bgkmap::viz {

// One box of the view: `level` 0 is one map cell; level L covers 2^L cells per side from
// (x, y, z) * 2^L (cell indices at that level).
struct ViewCell {
  int32_t x = 0, y = 0, z = 0;
  uint8_t level = 0;
  float probability = 0;
  bool uncertain = false;  // variance above the map's var_threshold (BGK maps only)
  bool occupied = false;   // occupied by the map's own classification
};

struct ViewMap {
  double resolution_m = 0.1;
  float occupied_threshold = 0.7f;
  bool has_variance = false;
  std::string source;           // file name, shown in the page
  std::vector<ViewCell> cells;  // the candidates: probability >= kMinViewProbability
};

// Cells below this probability are never part of the view (the slider starts here).
inline constexpr float kMinViewProbability = 0.5f;
// Default cap on the cells a page holds: 1,000,000 boxes draw at interactive rates with WebGL on
// an integrated GPU, and make a page of about 12 MB.
inline constexpr size_t kDefaultMaxViewCells = 1000000;

// The candidates of a .bgk, .ot or .bt map: cells (OctoMap: leaves) with probability >= 0.5.
// Throws InputError naming the file when it cannot be read.
ViewMap read_view_map(const std::filesystem::path& file);

// The smallest cap: parents split at index 0 as OctoMap's do, so a map around the origin keeps
// at least one box per octant.
inline constexpr size_t kMinViewCap = 8;

// Above the cap, boxes are merged into their 2x2x2 parents (probability: the largest of the
// children; uncertain only if every child is; occupied if any child is) one level at a time until
// at most max_cells (>= kMinViewCap) remain: the whole map stays visible, coarser. Returns the
// level reached.
int merge_to_cap(ViewMap& map, size_t max_cells);

// How a map was fitted under the cap.
struct ViewReduction {
  int level = 0;                             // merge level reached (0: every cell as it is)
  float min_probability = kMinViewProbability;  // every candidate at or above it is in the page
};

// Fits the candidates under the cap, keeping what the page shows first at full resolution: the
// map's occupied cells, then the others (below the map's thresholds, or uncertain) from the most
// probable down, leaving out the lowest probabilities (whole: a probability is kept for every
// cell that has it or for none). Only when the occupied cells alone exceed the cap are the others
// all left out and the occupied ones merged (merge_to_cap).
ViewReduction fit_to_cap(ViewMap& map, size_t max_cells);

struct ViewStats {
  size_t map_cells = 0;  // the map's candidates
  size_t cells = 0;      // boxes in the page
  ViewReduction reduction;
  uint64_t bytes = 0;
};

// Writes the page atomically. Throws InputError (naming `file`) when the map is wider than the
// page's 16-bit coordinates allow (65,535 boxes per axis at the level reached), and
// std::invalid_argument for a cap under kMinViewCap.
ViewStats write_view_html(const std::filesystem::path& file, ViewMap map, size_t max_cells = kDefaultMaxViewCells);

}  // namespace bgkmap::viz
