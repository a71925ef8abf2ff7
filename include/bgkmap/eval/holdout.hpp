// Held-out beams, for scoring real data that has no truth (the protocol of the Bayesian Hilbert
// maps paper): a map is built on a random fraction of each scan's beams and tested on the others,
// their end points as occupied and points sampled along them as free.
//
// The split is a Bernoulli draw per beam from a counter-based hash of (seed, scan, beam): the
// same seed always holds out the same beams, on any machine and thread count.
// Free samples: every `spacing` metres from the origin (first one at `spacing`) up to one spacing
// short of the end point (short of the max range for a beam without a return), so that a free
// sample never lies in the cell of the beam's own hit.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/core/scan.hpp"
#include "bgkmap/eval/metrics.hpp"

namespace bgkmap::eval {

struct BeamSplit {
  std::vector<uint32_t> kept;      // indices into the scan's points, ascending
  std::vector<uint32_t> held_out;  // the rest, ascending
};

// Each beam is held out with probability `fraction` (in [0, 1]); throws std::invalid_argument otherwise.
BeamSplit split_beams(size_t beam_count, double fraction, uint64_t seed, uint64_t scan_index);

// The scan restricted to the given point indices (same pose and source).
Scan select_beams(const Scan& scan, const std::vector<uint32_t>& indices);

// Probability of "occupied" at a world point (a map's or a method's; kUnknownScore where it knows
// nothing, see scored_map.hpp).
using PointScore = std::function<double(double x, double y, double z)>;

// Adds the held-out beams' samples, scored by `score`. Non-finite points are skipped;
// preprocessing's max range and viewpoint transform apply as in the build. Returns the number of
// beams used.
size_t add_holdout_samples(const Scan& held_out, const PreprocessParams& params, double spacing,
                           const PointScore& score, LabelledScores& out);

}  // namespace bgkmap::eval
