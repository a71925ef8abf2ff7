// The Bayesian Hilbert maps paper's Table 2 protocol (Senanayake & Ramos 2018, "Experiments"):
// "10% of randomly chosen data that were never used for training were used to compute these
// metrics", AUC and NLL reported as their mean +- 2 sigma over the sequence of updates.
//
// Here: each scan's beams are split as the per-beam hold-out (split_beams, `fraction` of them held
// out, the same split for the same seed); the map is updated on the kept beams scan by scan, and
// after every `every`-th update (and after the last) scored on the held-out samples
// (for_each_holdout_sample: each held-out beam's end point occupied, its free samples free) of
// every scan so far. The summary is the mean and twice the sample standard deviation (n - 1) of
// the updates' AUC and NLL, updates whose AUC is undefined (one class only) left out of both.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/metrics.hpp"

namespace bgkmap::eval {

struct UpdateSequenceParams {
  double fraction = 0.1;  // of each scan's beams held out, in [0, 1]
  uint64_t seed = 1;
  double spacing = 0.1;   // of the free samples along a held-out beam (m), > 0
  uint64_t every = 1;     // score after every this many updates, >= 1
  double occupied_threshold = 0.5;
  PreprocessParams preprocess;
};

struct UpdateScore {
  uint64_t scans = 0;  // updates so far
  BinaryMetrics metrics;
};

// Mean and twice the sample standard deviation of the finite values (NaN: none, or one value's
// two_sigma); `count` of them.
struct MeanTwoSigma {
  double mean = 0, two_sigma = 0;
  uint64_t count = 0;
};
MeanTwoSigma mean_two_sigma(const std::vector<double>& values);

struct UpdateSequenceResult {
  std::vector<UpdateScore> updates;  // in order
  MeanTwoSigma auc, nll;             // over the updates with both classes in the test set
  uint64_t scans = 0, kept_beams = 0, held_beams = 0;
};

// next(scan): the next scan, false at the end; insert(kept): one update on the kept beams;
// score: the map's probability at a point (kUnknownScore where it knows nothing); scored(k):
// called after each scoring (progress). Throws std::invalid_argument for bad params.
UpdateSequenceResult run_update_sequence(const std::function<bool(Scan&)>& next,
                                         const std::function<void(const Scan&)>& insert, const PointScore& score,
                                         const UpdateSequenceParams& params,
                                         const std::function<void(uint64_t)>& scored = {});

}  // namespace bgkmap::eval
