// Held-out data, for scoring real data that has no truth. Two splits:
//  - beams (the Bayesian Hilbert maps paper's per-beam protocol): a map is built on a random
//    fraction of each scan's beams and tested on the others. The split is a Bernoulli draw per
//    beam from a counter-based hash of (seed, scan, beam): the same seed always holds out the
//    same beams, on any machine and thread count.
//  - whole scans (the Hilbert maps / Bayesian Hilbert maps evaluation on the Intel log): the
//    scans are cut into runs of `run_length` consecutive scans and round(fraction x runs) runs
//    (at least one when fraction > 0) are held out, the runs ranked by a hash of (seed, run).
//    A held-out scan's place was never seen from there, so this is the harder test.
// Either way each held-out beam gives its end point as occupied and points sampled along it as
// free: every `spacing` metres from the origin (first one at `spacing`) up to one spacing short
// of the end point (short of the max range for a beam without a return within it), so that a
// free sample never lies in the cell of the beam's own hit.
#pragma once

#include <cstdint>
#include <filesystem>
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

// Calls `sample(x, y, z, occupied)` for each sample of the held-out beams, in beam order (end
// point, then free samples outwards). The points are taken as the build takes them
// (usable_points without downsampling: world frame, NaN/Inf dropped, a sensor's no-return
// readings made beams beyond the max range or dropped); max range (BeyondRange) as in the build.
// Returns the number of beams used. Throws std::invalid_argument unless spacing > 0.
using SampleVisitor = std::function<void(double x, double y, double z, bool occupied)>;
size_t for_each_holdout_sample(const Scan& held_out, const PreprocessParams& params, double spacing,
                               const SampleVisitor& sample);

// Adds the held-out beams' samples, scored by `score`. Returns the number of beams used.
size_t add_holdout_samples(const Scan& held_out, const PreprocessParams& params, double spacing,
                           const PointScore& score, LabelledScores& out);

// --- Whole scans held out -------------------------------------------------------------------

struct ScanHoldoutParams {
  double fraction = 0.1;   // of the runs (so about of the scans), in [0, 1]
  size_t run_length = 10;  // consecutive scans per run, >= 1
  uint64_t seed = 1;
};

// held_out[i]: scan i is held out. Throws std::invalid_argument for a fraction outside [0, 1]
// or run_length 0.
std::vector<bool> split_scans(size_t scan_count, const ScanHoldoutParams& params);

// The held-out samples as points, for scoring any method (score each, then compute_metrics);
// in double, so that scoring them gives exactly what add_holdout_samples gives.
struct LabelledPoints {
  std::vector<Vec3d> occupied;
  std::vector<Vec3d> free;
};
LabelledPoints holdout_points(const std::vector<Scan>& held_out, const PreprocessParams& params, double spacing);

// Scores every point: occupied points are the positives, free ones the negatives.
LabelledScores score_points(const LabelledPoints& points, const PointScore& score);

// A whole-scan split of scan files/folders read into memory (small logs: the Intel log is 2 MB
// of points), for methods and tests that map the training scans themselves:
//   WholeScanSplit s = split_whole_scans({"intel-corrected.log.gz"}, {});
//   for (const Scan& scan : s.training) method.insert(scan);
//   LabelledScores scores = score_points(holdout_points(s.held_out, pre, 0.1), score);
// Throws InputError as ScanSource does.
struct WholeScanSplit {
  std::vector<Scan> training;             // the other scans, in order
  std::vector<Scan> held_out;             // in order
  std::vector<uint32_t> held_out_indices;  // their indices among all scans
};
WholeScanSplit split_whole_scans(const std::vector<std::filesystem::path>& inputs, const ScanHoldoutParams& params);

}  // namespace bgkmap::eval
