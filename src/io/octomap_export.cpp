// The only translation unit that includes OctoMap's headers to write maps: .ot (classified cells,
// or every cell's probability, as log-odds) and .bt (the map's occupied / free classification).
//
// Cell correspondence: bgkmap cell i covers [i*r, (i+1)*r) (core/grid.hpp) and OctoMap's key of
// a coordinate x is floor(x/r) + 32768 at the finest depth, so cell i is OctoMap key i + 32768;
// keys are set directly from cell indices, never through coordinates.
#include <octomap/OcTree.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <optional>
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
void keep_probabilities_unclamped(octomap::OcTree& tree) {
  tree.setClampingThresMin(kMinProbability);
  tree.setClampingThresMax(1.0 - kMinProbability);
}

// AbstractOcTree::write with `comment` after the first line (its header, then writeData).
bool write_commented_tree(std::ostream& out, const octomap::OcTree& tree, const std::string& comment) {
  out << "# Octomap OcTree file\n" << comment
      << "\n# (feel free to add / change comments, but leave the first line as it is!)\n#\n";
  out << "id " << tree.getTreeType() << "\nsize " << tree.size() << "\nres " << tree.getResolution() << "\ndata\n";
  tree.writeData(out);
  return out.good();
}

const char kTreeValuesCommentPrefix[] = "# bgkmap ot-values ";

// The probability of an occupied or free cell moved onto OctoMap's side of 0.5 where its
// threshold lies on the other side (classified_log_odds).
double on_octomaps_side(double probability, CellState state, const ClassifyParams& classify) {
  const double occupied = classify.occupied_threshold, free = classify.free_threshold;
  if (state == CellState::kOccupied && occupied < 0.5) return 0.5 + 0.5 * (probability - occupied) / (1 - occupied);
  if (state == CellState::kFree && free > 0.5) return 0.5 * probability / free;
  return probability;
}

}  // namespace

void write_tree_atomically(const std::filesystem::path& file, octomap::OcTree& tree, bool binary,
                           const std::string& comment) {
  write_file_atomically(file, [&](std::ostream& out) {
    out.precision(round_trip_digits(tree.getResolution()));
    bool written;
    {
      const QuietStderr quiet;
      if (binary) written = tree.writeBinary(out);
      else written = comment.empty() ? tree.write(out) : write_commented_tree(out, tree, comment);
    }
    if (!written) throw std::runtime_error(file.string() + ": OctoMap could not write the tree");
  });
}

std::string tree_values_comment(TreeValues values) { return kTreeValuesCommentPrefix + std::string(to_string(values)); }

std::optional<TreeValues> tree_values_in_comment(const std::string& line) {
  for (const TreeValues values : {TreeValues::kClassified, TreeValues::kMean})
    if (line == tree_values_comment(values)) return values;
  return std::nullopt;
}

float classified_log_odds(double probability, CellState state, const ClassifyParams& classify) {
  const float log_odds = octomap::logodds(clamp_probability(on_octomaps_side(probability, state, classify)));
  // Rounding must not carry a value across OctoMap's rule: log-odds >= 0 is occupied.
  return state == CellState::kOccupied ? std::max(log_odds, 0.0f)
                                       : std::min(log_odds, -std::numeric_limits<float>::min());
}

namespace {

// Hands every cell a map knows to the visitor: its probability and the map's class of it.
using ClassifiedCellVisitor = std::function<void(const CellIndex& cell, double probability, CellState state)>;
using ClassifiedCells = std::function<void(const ClassifiedCellVisitor& visit)>;

// The one tree writer. .bt: occupied and free cells at OctoMap's default clamping bounds, well
// clear of the 0.5 threshold writeBinary classifies by. .ot, classified: those cells at
// classified_log_odds; mean: every cell's probability. Log-odds of probabilities clamped to
// [1e-6, 1 - 1e-6], stored unchanged.
void write_cells_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                      const ClassifiedCells& cells, bool binary, TreeValues ot_values) {
  octomap::OcTree tree(resolution_m);
  const float occupied = tree.getClampingThresMaxLog();
  const float free = tree.getClampingThresMinLog();
  if (!binary) keep_probabilities_unclamped(tree);
  const bool every_cell = !binary && ot_values == TreeValues::kMean;
  // The tree grows by a leaf and its share of inner nodes and child arrays per cell (about 80
  // bytes where cells are sparse): checked against the memory limit a chunk of cells ahead.
  constexpr double kBytesPerTreeCell = 80;
  constexpr uint64_t kCellsPerCheck = uint64_t{1} << 16;
  uint64_t visited = 0;
  cells([&](const CellIndex& cell, double p, CellState state) {
    if (state == CellState::kUnknown && !every_cell) return;
    if (visited++ % kCellsPerCheck == 0)
      require_memory(kCellsPerCheck * kBytesPerTreeCell,
                     "the OctoMap tree of " + file.filename().string() + " (" + std::to_string(visited - 1) +
                         " cells so far)",
                     "give a coarser --resolution (or raise --max-memory)");
    float log_odds;
    if (binary) log_odds = state == CellState::kOccupied ? occupied : free;
    else if (every_cell) log_odds = octomap::logodds(clamp_probability(p));
    else log_odds = classified_log_odds(p, state, classify);
    tree.setNodeValue(octomap_key_of(file, cell), log_odds, /*lazy_eval=*/true);
  });
  tree.updateInnerOccupancy();  // inner nodes once at the end: max of the children, lossless
  if (!binary) tree.prune();    // merges only 8 identical leaves: lossless
  // writeBinary: max-likelihood states, pruned; a .ot names what it holds in a comment line.
  write_tree_atomically(file, tree, binary, binary ? "" : tree_values_comment(ot_values));
}

// A BGK map's cells with evidence: posterior mean and CellPosterior::state.
ClassifiedCells bgk_cells(const BgkMap& map) {
  return [&map](const ClassifiedCellVisitor& visit) {
    const ClassifyParams& classify = map.params().classify;
    map.for_each_cell_with_evidence(
        [&](const CellIndex& cell, const CellPosterior& p) { visit(cell, p.mean(), p.state(classify)); });
  };
}

}  // namespace

void write_octomap_tree(const std::filesystem::path& file, const BgkMap& map, TreeValues values) {
  write_cells_tree(file, map.grid().resolution(), map.params().classify, bgk_cells(map), /*binary=*/false, values);
}

void write_octomap_binary(const std::filesystem::path& file, const BgkMap& map) {
  write_cells_tree(file, map.grid().resolution(), map.params().classify, bgk_cells(map), /*binary=*/true,
                   TreeValues::kClassified);
}

void require_tree_output(const std::filesystem::path& file, const std::string& method) {
  const MapFormat format = map_format_from_path(file);
  if (format != MapFormat::kOctomapTree && format != MapFormat::kOctomapBinary)
    throw InputError(file, "--method " + method + " writes OctoMap trees only (.ot or .bt)");
}

void write_probability_tree(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                            const CellProbabilities& cells, TreeValues ot_values) {
  const MapFormat format = map_format_from_path(file);
  if (format != MapFormat::kOctomapTree && format != MapFormat::kOctomapBinary)
    throw InputError(file, "a probability tree is written as an OctoMap tree (.ot or .bt)");
  const ClassifiedCells classified = [&](const ClassifiedCellVisitor& visit) {
    cells([&](const CellIndex& cell, double p) { visit(cell, p, state_of_probability(p, classify)); });
  };
  write_cells_tree(file, resolution_m, classify, classified, format == MapFormat::kOctomapBinary, ot_values);
}

}  // namespace bgkmap
