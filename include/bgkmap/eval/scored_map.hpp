// A map as `bgkmap eval` scores it, whatever wrote it: every method's map files read through one
// interface, so that all of them are scored by the same code on the same cells.
//
// Formats:
//   .bgk  native BgkMap: score = posterior mean alpha / (alpha + beta), variance of the Beta;
//         occupied threshold = the map's classify threshold (--occupied-threshold at build time)
//   .ot   OctoMap OcTree (AbstractOcTree::read; any other tree type is refused): score = the
//         node's probability (OctoMap's own for --method octomap, the log-odds of the posterior
//         mean or squashed probability for the other methods, written with --ot-values mean);
//         no variance. A bgkmap .ot of classified cells (--ot-values classified, the default)
//         says so (is_classified_tree): eval refuses it, since the cells left out would score 0.5
//   .bt   OctoMap binary tree: holds only max-likelihood states, read back at OctoMap's default
//         clamping probabilities (0.1192 free, 0.971 occupied), so it ranks cells in two groups;
//         score the .ot of the same map for the method's probabilities
// OctoMap files do not store an occupancy threshold: trees use OctoMap's default (0.5).
//
// A point where the map has no evidence (a BGK cell at the prior, a point outside every tree
// leaf) scores kUnknownScore, the same for every method.
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/map/bgk_map.hpp"
#include "bgkmap/sim/vec_math.hpp"

namespace bgkmap::eval {

constexpr double kUnknownScore = 0.5;

struct MapSample {
  double score = kUnknownScore;  // probability of "occupied"
  bool has_evidence = false;
  std::optional<double> variance;  // where the format keeps one (BGK: also at the prior)
};

class ScoredMap {
 public:
  virtual ~ScoredMap() = default;

  double resolution() const { return grid_.resolution(); }
  // The map's cells: cell i covers [i r, (i + 1) r) per axis, as OctoMap's keys do.
  const Grid& grid() const { return grid_; }
  // Box (metres) around every cell or leaf with evidence; empty (min > max) if there is none.
  virtual sim::Box3d observed_bounds() const = 0;
  virtual MapSample sample(double x, double y, double z) const = 0;
  // Whether sample() gives a variance.
  virtual bool has_variance() const = 0;
  // Score above which the map predicts "occupied" (accuracy, precision, recall).
  virtual double occupied_threshold() const = 0;
  // Score below which the map calls a cell free: a .bgk's --free-threshold; OctoMap's trees call
  // a node below their occupancy threshold free.
  virtual double free_threshold() const { return occupied_threshold(); }
  // The cells scoring above occupied_threshold(), any order: a pruned tree leaf of 2 x 2 x 2 as
  // each of its cells, larger ones (solid blocks, no thin walls) left out.
  virtual std::vector<CellIndex> occupied_cells() const = 0;
  // A .ot bgkmap wrote with --ot-values classified: only the cells its method classified.
  virtual bool is_classified_tree() const { return false; }

 protected:
  explicit ScoredMap(double resolution);

 private:
  Grid grid_;
};

// From the extension (.bgk, .ot or .bt, case-insensitive). Throws InputError naming the file when
// it is missing, of another format, unreadable, truncated or corrupt, or (.ot) not an OcTree.
std::unique_ptr<ScoredMap> load_scored_map(const std::filesystem::path& file);

// A BGK map already in memory (what load_scored_map gives for its .bgk file).
std::unique_ptr<ScoredMap> make_scored_map(BgkMap map);

// OctoMap's occupancy threshold for trees that do not set one (0.5).
double octomap_default_occupied_threshold();

// The sample of a probability a method reports (nullopt: no evidence, kUnknownScore).
MapSample sample_of_probability(std::optional<double> probability);

}  // namespace bgkmap::eval
