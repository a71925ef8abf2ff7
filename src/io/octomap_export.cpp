// The only translation unit that includes OctoMap's headers to write maps: .ot (posterior means
// as log-odds) and .bt (the map's occupied / free classification).
//
// Cell correspondence: bgkmap cell i covers [i*r, (i+1)*r) (core/grid.hpp) and OctoMap's key of
// a coordinate x is floor(x/r) + 32768 at the finest depth, so cell i is OctoMap key i + 32768;
// keys are set directly from cell indices, never through coordinates.
#include <octomap/OcTree.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "io/octomap_tree_write.hpp"
#include "io/probability_tree.hpp"
#include "io/quiet_stderr.hpp"

namespace bgkmap {

namespace {

// Probabilities are clamped to [kMinProbability, 1 - kMinProbability] before the logit: the
// posterior mean of a cell with overwhelming evidence would otherwise give +-inf log-odds.
constexpr double kMinProbability = 1e-6;
constexpr int64_t kOctomapKeyOffset = 32768;  // OctoMap's tree_max_val (16 levels)

octomap::OcTreeKey octomap_key_of(const std::filesystem::path& file, const CellIndex& cell) {
  const auto axis_key = [&](int32_t index) {
    const int64_t key = static_cast<int64_t>(index) + kOctomapKeyOffset;
    if (key < 0 || key > 0xFFFF)
      throw std::runtime_error(file.string() + ": cell index " + std::to_string(index) +
                               " is outside OctoMap's range of +-32768 cells per axis");
    return static_cast<octomap::key_type>(key);
  };
  return octomap::OcTreeKey(axis_key(cell.x), axis_key(cell.y), axis_key(cell.z));
}

// OctoMap prints the resolution with the stream's precision (6 digits by default, too few for
// e.g. 0.0123456789): the fewest digits that read back exactly (0.1 stays "0.1").
int round_trip_digits(double value) {
  for (int digits = 6; digits < std::numeric_limits<double>::max_digits10; ++digits) {
    std::ostringstream printed;
    printed.precision(digits);
    printed << value;
    std::istringstream parsed(printed.str());  // as OctoMap reads it back: `stream >> res`
    double back = 0;
    parsed >> back;
    if (back == value) return digits;
  }
  return std::numeric_limits<double>::max_digits10;
}

double clamp_probability(double p) { return std::clamp(p, kMinProbability, 1.0 - kMinProbability); }

// A tree that stores log-odds of probabilities in [kMinProbability, 1 - kMinProbability]
// unchanged: its clamping at exactly that range, through the same logodds().
void keep_probabilities_unclamped(octomap::OcTree& tree, double occupied_threshold) {
  tree.setClampingThresMin(kMinProbability);
  tree.setClampingThresMax(1.0 - kMinProbability);
  tree.setOccupancyThres(clamp_probability(occupied_threshold));
}

}  // namespace

void write_tree_atomically(const std::filesystem::path& file, octomap::OcTree& tree, bool binary) {
  write_file_atomically(file, [&](std::ostream& out) {
    out.precision(round_trip_digits(tree.getResolution()));
    bool written;
    {
      const QuietStderr quiet;
      written = binary ? tree.writeBinary(out) : tree.write(out);
    }
    if (!written) throw std::runtime_error(file.string() + ": OctoMap could not write the tree");
  });
}

namespace {

// The one tree writer: .ot keeps each cell's probability (log-odds, clamped to [1e-6, 1 - 1e-6]
// and stored unchanged); .bt keeps the thresholds' decision at OctoMap's default clamping bounds,
// well clear of the 0.5 occupancy threshold writeBinary classifies by; undecided cells are left out.
void write_cells_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                      const CellProbabilities& cells, bool binary) {
  octomap::OcTree tree(resolution_m);
  const float occupied = tree.getClampingThresMaxLog();
  const float free = tree.getClampingThresMinLog();
  if (!binary) keep_probabilities_unclamped(tree, classify.occupied_threshold);
  // The tree grows by a leaf and its share of inner nodes and child arrays per cell (about 80
  // bytes where cells are sparse): checked against the memory limit a chunk of cells ahead.
  constexpr double kBytesPerTreeCell = 80;
  constexpr uint64_t kCellsPerCheck = uint64_t{1} << 16;
  uint64_t visited = 0;
  cells([&](const CellIndex& cell, double p) {
    if (visited++ % kCellsPerCheck == 0)
      require_memory(kCellsPerCheck * kBytesPerTreeCell,
                     "the OctoMap tree of " + file.filename().string() + " (" + std::to_string(visited - 1) +
                         " cells so far)",
                     "give a coarser --resolution (or raise --max-memory)");
    float log_odds;
    if (binary) {
      if (p > classify.occupied_threshold) log_odds = occupied;
      else if (p < classify.free_threshold) log_odds = free;
      else return;
    } else {
      log_odds = octomap::logodds(clamp_probability(p));
    }
    tree.setNodeValue(octomap_key_of(file, cell), log_odds, /*lazy_eval=*/true);
  });
  tree.updateInnerOccupancy();  // inner nodes once at the end: max of the children, lossless
  if (!binary) tree.prune();    // merges only 8 identical leaves: lossless
  write_tree_atomically(file, tree, binary);  // writeBinary: max-likelihood states, pruned
}

// A BGK map's cells with evidence and their posterior means; for .bt only the cells certain
// enough to be decided (variance within classify.var_threshold, as CellPosterior::state).
CellProbabilities bgk_cells(const BgkMap& map, bool decided_only) {
  return [&map, decided_only](const CellProbabilityVisitor& visit) {
    const double var_threshold = map.params().classify.var_threshold;
    map.for_each_cell_with_evidence([&](const CellIndex& cell, const CellPosterior& p) {
      if (decided_only && p.variance() > var_threshold) return;
      visit(cell, p.mean());
    });
  };
}

}  // namespace

void write_octomap_tree(const std::filesystem::path& file, const BgkMap& map) {
  write_cells_tree(file, map.grid().resolution(), map.params().classify, bgk_cells(map, false), /*binary=*/false);
}

void write_octomap_binary(const std::filesystem::path& file, const BgkMap& map) {
  write_cells_tree(file, map.grid().resolution(), map.params().classify, bgk_cells(map, true), /*binary=*/true);
}

void require_tree_output(const std::filesystem::path& file, const std::string& method) {
  if (map_format_from_path(file) == MapFormat::kNative)
    throw InputError(file, "--method " + method + " writes OctoMap trees only (.ot or .bt), not a native .bgk map");
}

void write_probability_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                            const CellProbabilities& cells) {
  const MapFormat format = map_format_from_path(file);
  if (format == MapFormat::kNative) throw InputError(file, "a probability map is written as an OctoMap tree (.ot or .bt)");
  write_cells_tree(file, resolution_m, classify, cells, format == MapFormat::kOctomapBinary);
}

}  // namespace bgkmap
