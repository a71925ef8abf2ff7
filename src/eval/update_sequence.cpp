#include "bgkmap/eval/update_sequence.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

namespace bgkmap::eval {

MeanTwoSigma mean_two_sigma(const std::vector<double>& values) {
  MeanTwoSigma s;
  double sum = 0;
  for (double v : values)
    if (std::isfinite(v)) {
      sum += v;
      ++s.count;
    }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  if (s.count == 0) return {nan, nan, 0};
  s.mean = sum / double(s.count);
  if (s.count == 1) {
    s.two_sigma = nan;
    return s;
  }
  double squares = 0;
  for (double v : values)
    if (std::isfinite(v)) squares += (v - s.mean) * (v - s.mean);
  s.two_sigma = 2.0 * std::sqrt(squares / double(s.count - 1));
  return s;
}

UpdateSequenceResult run_update_sequence(const std::function<bool(Scan&)>& next,
                                         const std::function<void(const Scan&)>& insert, const PointScore& score,
                                         const UpdateSequenceParams& params,
                                         const std::function<void(uint64_t)>& scored) {
  if (!(params.spacing > 0)) throw std::invalid_argument("the free sample spacing must be > 0");
  if (params.every < 1) throw std::invalid_argument("the scoring interval must be at least 1 update");
  UpdateSequenceResult result;
  LabelledPoints test;  // the held-out samples of every scan so far
  const auto score_now = [&] {
    result.updates.push_back({result.scans, compute_metrics(score_points(test, score), params.occupied_threshold)});
    if (scored) scored(result.scans);
  };
  Scan scan;
  while (next(scan)) {
    const BeamSplit split = split_beams(scan.points.size(), params.fraction, params.seed, result.scans);
    insert(select_beams(scan, split.kept));
    for_each_holdout_sample(select_beams(scan, split.held_out), params.preprocess, params.spacing,
                            [&](double x, double y, double z, bool occupied) {
                              (occupied ? test.occupied : test.free).push_back({x, y, z});
                            });
    result.kept_beams += split.kept.size();
    result.held_beams += split.held_out.size();
    if (++result.scans % params.every == 0) score_now();
  }
  if (result.scans > 0 && result.scans % params.every != 0) score_now();
  std::vector<double> auc, nll;
  for (const UpdateScore& u : result.updates) {
    if (!std::isfinite(u.metrics.auc)) continue;  // one class only: neither metric counted
    auc.push_back(u.metrics.auc);
    nll.push_back(u.metrics.nll);
  }
  result.auc = mean_two_sigma(auc);
  result.nll = mean_two_sigma(nll);
  return result;
}

}  // namespace bgkmap::eval
