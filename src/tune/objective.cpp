#include "bgkmap/tune/objective.hpp"

namespace bgkmap::tune {

double objective_value(const eval::BinaryMetrics& metrics, Objective objective) {
  return objective == Objective::kNll ? metrics.nll : 1.0 - metrics.auc;
}

double objective_value(const eval::LabelledScores& scores, Objective objective) {
  return objective == Objective::kNll ? eval::mean_nll(scores) : 1.0 - eval::roc_auc(scores);
}

}  // namespace bgkmap::tune
