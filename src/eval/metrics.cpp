#include "bgkmap/eval/metrics.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <utility>

namespace bgkmap::eval {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Walks the thresholds from the highest score down: for each distinct score, the cumulative
// true and false positives once every sample with that score is predicted occupied.
void for_each_threshold(const LabelledScores& scores, const std::function<void(double tp, double fp)>& visit) {
  std::vector<std::pair<double, bool>> samples;
  samples.reserve(scores.positive.size() + scores.negative.size());
  for (double s : scores.positive) samples.emplace_back(s, true);
  for (double s : scores.negative) samples.emplace_back(s, false);
  std::sort(samples.begin(), samples.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  double tp = 0, fp = 0;
  for (size_t i = 0; i < samples.size();) {
    size_t j = i;
    for (; j < samples.size() && samples[j].first == samples[i].first; ++j) (samples[j].second ? tp : fp) += 1;
    visit(tp, fp);
    i = j;
  }
}

}  // namespace

double roc_auc(const LabelledScores& scores) {
  const double p = scores.positive.size(), n = scores.negative.size();
  if (p == 0 || n == 0) return kNaN;
  // Trapezoids between thresholds: a tied group contributes half its positive x negative pairs.
  double area = 0, prev_tp = 0, prev_fp = 0;
  for_each_threshold(scores, [&](double tp, double fp) {
    area += (fp - prev_fp) * (tp + prev_tp) / 2.0;
    prev_tp = tp;
    prev_fp = fp;
  });
  return area / (p * n);
}

double average_precision(const LabelledScores& scores) {
  const double p = scores.positive.size();
  if (p == 0) return kNaN;
  double ap = 0, prev_tp = 0;
  for_each_threshold(scores, [&](double tp, double fp) {
    ap += (tp - prev_tp) / p * (tp / (tp + fp));
    prev_tp = tp;
  });
  return ap;
}

double mean_nll(const LabelledScores& scores) {
  const size_t count = scores.positive.size() + scores.negative.size();
  if (count == 0) return kNaN;
  auto clamp = [](double s) { return std::min(std::max(s, kNllClamp), 1.0 - kNllClamp); };
  double sum = 0;
  for (double s : scores.positive) sum -= std::log(clamp(s));
  for (double s : scores.negative) sum -= std::log(1.0 - clamp(s));
  return sum / static_cast<double>(count);
}

BinaryMetrics compute_metrics(const LabelledScores& scores, double occupied_threshold) {
  BinaryMetrics m;
  m.n_positive = scores.positive.size();
  m.n_negative = scores.negative.size();
  m.auc = roc_auc(scores);
  m.average_precision = average_precision(scores);
  m.nll = mean_nll(scores);
  const double tp = std::count_if(scores.positive.begin(), scores.positive.end(),
                                  [&](double s) { return s > occupied_threshold; });
  const double fp = std::count_if(scores.negative.begin(), scores.negative.end(),
                                  [&](double s) { return s > occupied_threshold; });
  const double p = m.n_positive, n = m.n_negative;
  m.accuracy = p + n > 0 ? (tp + (n - fp)) / (p + n) : kNaN;
  m.precision = tp + fp > 0 ? tp / (tp + fp) : kNaN;
  m.recall = p > 0 ? tp / p : kNaN;
  return m;
}

Curves compute_curves(const LabelledScores& scores) {
  Curves c;
  const double p = scores.positive.size(), n = scores.negative.size();
  c.fpr.push_back(0);
  c.tpr.push_back(0);
  for_each_threshold(scores, [&](double tp, double fp) {
    c.fpr.push_back(n > 0 ? fp / n : 0);
    c.tpr.push_back(p > 0 ? tp / p : 0);
    c.recall.push_back(p > 0 ? tp / p : 0);
    c.precision.push_back(tp / (tp + fp));
  });
  return c;
}

}  // namespace bgkmap::eval
