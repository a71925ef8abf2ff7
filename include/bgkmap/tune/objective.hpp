// What `bgkmap tune` minimises: the held-out NLL, or 1 - AUC when it maximises the AUC.
#pragma once

#include "bgkmap/eval/metrics.hpp"

namespace bgkmap::tune {

enum class Objective { kNll, kAuc };

double objective_value(const eval::BinaryMetrics& metrics, Objective objective);
// The same from the scores, without the other metrics.
double objective_value(const eval::LabelledScores& scores, Objective objective);

}  // namespace bgkmap::tune
