// The data `bgkmap tune` works on: the training scans and two disjoint held-out sets, one that the
// search scores (the same beams or scans `bgkmap eval --holdout F --seed S` holds out) and one
// that only confirms the choice, so that a choice fitted to the first is caught on the second.
#pragma once

#include <cstdint>
#include <vector>

#include "bgkmap/core/scan.hpp"

namespace bgkmap::tune {

enum class SplitKind { kBeams, kScans };

struct TuneSplitParams {
  double fraction = 0.1;  // held out for the search, and as much again to confirm; in (0, 0.5)
  SplitKind kind = SplitKind::kBeams;
  size_t run_length = 10;  // kScans: consecutive scans per held-out run
  uint64_t seed = 1;
};

struct TuneSplit {
  std::vector<Scan> training;  // the beams (or scans) in neither held-out set, in order
  std::vector<Scan> search;    // held out for the search
  std::vector<Scan> confirm;   // held out to confirm, disjoint from `search`
};

// Throws std::invalid_argument for a fraction outside (0, 0.5) or run_length 0.
TuneSplit split_for_tuning(std::vector<Scan> scans, const TuneSplitParams& params);

// Every training scan, or `count` of them evenly spread (count 0 or beyond the size: all).
std::vector<Scan> spread_subset(const std::vector<Scan>& scans, size_t count);

}  // namespace bgkmap::tune
