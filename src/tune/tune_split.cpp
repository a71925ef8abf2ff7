#include "bgkmap/tune/tune_split.hpp"

#include <stdexcept>

#include "bgkmap/eval/holdout.hpp"
#include "core/splitmix.hpp"

namespace bgkmap::tune {

namespace {

// The second split's seed: derived, so that seeds S and S + 1 do not share it.
uint64_t confirm_seed(uint64_t seed) { return splitmix64(seed ^ 0xC0F1A3ull); }

// The entries of `from` at `positions`.
std::vector<uint32_t> pick(const std::vector<uint32_t>& from, const std::vector<uint32_t>& positions) {
  std::vector<uint32_t> out;
  out.reserve(positions.size());
  for (uint32_t p : positions) out.push_back(from[p]);
  return out;
}

TuneSplit split_beams(std::vector<Scan> scans, const TuneSplitParams& params) {
  // The confirming fraction of what the search leaves, so that both hold out about `fraction`.
  const double second = params.fraction / (1.0 - params.fraction);
  TuneSplit split;
  for (size_t i = 0; i < scans.size(); ++i) {
    const eval::BeamSplit first = eval::split_beams(scans[i].points.size(), params.fraction, params.seed, i);
    const eval::BeamSplit rest = eval::split_beams(first.kept.size(), second, confirm_seed(params.seed), i);
    split.search.push_back(eval::select_beams(scans[i], first.held_out));
    split.confirm.push_back(eval::select_beams(scans[i], pick(first.kept, rest.held_out)));
    split.training.push_back(eval::select_beams(scans[i], pick(first.kept, rest.kept)));
  }
  return split;
}

TuneSplit split_scans(std::vector<Scan> scans, const TuneSplitParams& params) {
  const std::vector<bool> first = eval::split_scans(scans.size(), {params.fraction, params.run_length, params.seed});
  std::vector<Scan> rest;
  TuneSplit split;
  for (size_t i = 0; i < scans.size(); ++i) (first[i] ? split.search : rest).push_back(std::move(scans[i]));
  const double second = params.fraction / (1.0 - params.fraction);
  const std::vector<bool> held = eval::split_scans(rest.size(), {second, params.run_length, confirm_seed(params.seed)});
  for (size_t i = 0; i < rest.size(); ++i) (held[i] ? split.confirm : split.training).push_back(std::move(rest[i]));
  return split;
}

}  // namespace

TuneSplit split_for_tuning(std::vector<Scan> scans, const TuneSplitParams& params) {
  if (!(params.fraction > 0 && params.fraction < 0.5))
    throw std::invalid_argument("the held-out fraction must be in (0, 0.5): tune holds it out twice");
  if (params.run_length == 0) throw std::invalid_argument("the held-out run length must be at least 1 scan");
  return params.kind == SplitKind::kBeams ? split_beams(std::move(scans), params) : split_scans(std::move(scans), params);
}

std::vector<Scan> spread_subset(const std::vector<Scan>& scans, size_t count) {
  if (count == 0 || count >= scans.size()) return scans;
  std::vector<Scan> out;
  out.reserve(count);
  for (size_t k = 0; k < count; ++k) out.push_back(scans[k * scans.size() / count]);
  return out;
}

}  // namespace bgkmap::tune
