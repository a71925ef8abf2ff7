// BGK-L's counts are linear in sigma0: a cell's alpha is alpha0 + sigma0 A and its beta
// beta0 + sigma0 B, where A and B are the kernel sums of its hits and free segments. Kept per
// held-out sample from one build, they give the held-out scores of any sigma0 and prior without
// rebuilding, so tune rebuilds only for a new l. The posterior mean that NLL and AUC score depends
// on alpha0 / sigma0 and beta0 / sigma0 only.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap::tune {

struct KernelSums {
  double hits = 0, free = 0;  // A and B
  bool evidence = false;      // no evidence: the map knows nothing there (eval::kUnknownScore)
};

struct HeldOutSums {
  std::vector<KernelSums> occupied, free;  // per sample of eval::LabelledPoints, in its order
};

// The posterior of the cell holding a point (has_evidence false where the map knows nothing).
using PosteriorAt = std::function<CellPosterior(double x, double y, double z)>;

// The sums of every held-out sample, from posteriors built with this sigma0 and prior.
HeldOutSums held_out_sums(const eval::LabelledPoints& points, const PosteriorAt& posterior, double sigma0,
                          double alpha0, double beta0);

// The scores (posterior means) the samples get under sigma0 and a prior.
eval::LabelledScores scores_from_sums(const HeldOutSums& sums, double sigma0, double alpha0, double beta0);

}  // namespace bgkmap::tune
