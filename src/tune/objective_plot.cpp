// The objective of a tune run's trials against each parameter (eval's line panels, markers only).
#include "bgkmap/tune/objective_plot.hpp"

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "bgkmap/eval/plot.hpp"
#include "bgkmap/tune/objective.hpp"
#include "bgkmap/tune/tunable.hpp"

namespace bgkmap::tune {

namespace {

// The objective of the first successful trial of `phase`, or built with exactly `values` when
// phase is empty; NaN when there is none.
double objective_of(const TuneResult& r, const std::string& phase, const std::vector<double>& values) {
  for (const Trial& t : r.trials)
    if (t.error.empty() && (phase.empty() ? t.values == values : t.phase == phase)) return t.objective;
  return std::numeric_limits<double>::quiet_NaN();
}

eval::LineSeries marker(const std::string& label, double x, double y) {
  return {label, {x}, {y}, false};
}

}  // namespace

void write_objective_plot(const std::filesystem::path& file, const std::string& method, const TuneResult& result,
                          Objective objective) {
  const std::vector<TunableParam>& table = tunable_params(method);
  const std::string ylabel = objective == Objective::kAuc ? "1 - AUC (search split)" : "held-out NLL (search split)";
  // The given values are the first trial's (the search's start, as it rounds them).
  const double given_y = objective_of(result, "start", {}), chosen_y = objective_of(result, "", result.chosen);
  std::vector<eval::LinePanel> panels;
  for (size_t i = 0; i < result.names.size(); ++i) {
    eval::LinePanel panel;
    panel.title = result.names[i];
    panel.xlabel = result.names[i] + (table[i].log_scale ? " (log)" : "");
    panel.ylabel = ylabel;
    panel.log_x = table[i].log_scale;
    eval::LineSeries trials{"trials", {}, {}, false};
    for (const Trial& t : result.trials) {
      if (!t.error.empty()) continue;
      trials.x.push_back(t.values[i]);
      trials.y.push_back(t.objective);
    }
    if (result.chosen == result.defaults)
      panel.series = {trials, marker("chosen: the given values", result.chosen[i], chosen_y)};
    else
      panel.series = {trials, marker("given", result.defaults[i], given_y), marker("chosen", result.chosen[i], chosen_y)};
    panels.push_back(std::move(panel));
  }
  const int columns = panels.size() < 3 ? static_cast<int>(panels.size()) : 3;
  eval::write_line_panels_png(file, panels, columns,
                              "bgkmap tune --method " + method + ": " + std::to_string(result.trials.size()) + " trials");
}

}  // namespace bgkmap::tune
