// Choosing a method's parameters from the data (`bgkmap tune`): the parameters of its table
// (tunable.hpp) that minimise the held-out NLL (or maximise the AUC) of the search split, by a
// DIRECT-L then BOBYQA search (unit_cube_search.hpp), each trial a build on the training scans
// (or an even subset of them; the given values are kept when the choice then loses to them on every
// training scan). BGK-L rebuilds only for l: each build's kernel sums give the best
// prior for it (prior_sums.hpp). The defaults and the choice are then built on every training
// scan and scored on both held-out splits (tune_split.hpp), the second one never seen by the search.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/tune/objective.hpp"
#include "bgkmap/tune/tunable.hpp"
#include "bgkmap/tune/tune_split.hpp"

namespace bgkmap::tune {

struct Trial {
  size_t index = 0;
  std::string phase;           // start (the given values), global or local
  std::vector<double> values;  // of every tunable_params(method) entry, in its order
  eval::BinaryMetrics metrics;  // on the search split
  double objective = 0;         // NLL, or 1 - AUC
  double seconds = 0;
  std::string error;  // a build that failed (its objective is then the worst)
};

struct TuneOptions {
  std::string method = "bgkl";
  BuildParams params;          // the given values: the search starts there, the rest stay
  MethodParams method_params;
  BackendOptions backend;
  TuneSplitParams split;
  double spacing = 0;  // free samples along held-out beams; 0: the resolution
  Objective objective = Objective::kNll;
  size_t budget = 0;   // builds in the search, the start included; 0: default_budget(method)
  double seconds = 0;  // > 0: no search build starts after this long (the result then depends on speed)
  double search_scans = 0;  // 0: every training scan; in (0, 1): that fraction; else that many
  std::function<void(const Trial&)> on_trial;  // called after each trial (progress)
};

struct SplitScores {
  eval::BinaryMetrics search, confirm;
};

struct TuneResult {
  std::vector<std::string> names;  // the tunable parameters' config keys
  std::vector<Range> ranges;       // searched, in their units
  std::vector<double> defaults, chosen;
  BuildParams params;  // the given ones with the choice set
  MethodParams method_params;
  std::vector<Trial> trials;
  SplitScores given_scores, tuned_scores;  // both built on every training scan
  // The best trial scored worse than the given values on the search split once built on every
  // training scan (possible with TuneOptions::search_scans): the given values are kept.
  bool kept_given = false;
  size_t scans = 0, training_scans = 0, search_training_scans = 0, search_held_scans = 0, confirm_held_scans = 0;
  double seconds = 0;        // the whole run
  double given_build_s = 0;  // one build of the given parameters on every training scan
};

// The search's builds when TuneOptions::budget is 0: 10 for bgkl (one parameter rebuilt), else 24.
size_t default_budget(const std::string& method);

// Throws std::invalid_argument for a method without a table, a bad split or budget, and
// std::runtime_error when no trial's build succeeded.
TuneResult tune(std::vector<Scan> scans, const TuneOptions& options);

}  // namespace bgkmap::tune
