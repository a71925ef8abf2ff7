// Scores of a binary occupancy classifier: the map's posterior mean as the score, the truth (or a
// held-out observation) as the label. Everything is computed from one sort of the scores, with
// equal scores forming one threshold (tie-aware: AUC equals the Mann-Whitney statistic with
// averaged ranks, so a constant score gives exactly 0.5).
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap::eval {

// Scores (probabilities of "occupied") of the samples whose label is occupied / free.
struct LabelledScores {
  std::vector<double> positive;
  std::vector<double> negative;
};

// Probabilities are clamped to [kNllClamp, 1 - kNllClamp] before taking logs.
constexpr double kNllClamp = 1e-6;

struct BinaryMetrics {
  double auc = 0;                // NaN when a class is empty
  double average_precision = 0;  // sum over thresholds of (recall step) x precision; NaN without positives
  double nll = 0;                // mean negative log-likelihood (natural log), clamped probabilities
  double accuracy = 0;           // at the occupied threshold: score > threshold predicts occupied
  double precision = 0;          // NaN when nothing is predicted occupied
  double recall = 0;             // NaN without positives
  uint64_t n_positive = 0, n_negative = 0;
};

// One point per distinct score (highest first), starting at (0, 0) for the ROC.
struct Curves {
  std::vector<double> fpr, tpr;           // ROC
  std::vector<double> recall, precision;  // precision-recall
};

double roc_auc(const LabelledScores& scores);
double average_precision(const LabelledScores& scores);
double mean_nll(const LabelledScores& scores);
BinaryMetrics compute_metrics(const LabelledScores& scores, double occupied_threshold);
Curves compute_curves(const LabelledScores& scores);

}  // namespace bgkmap::eval
