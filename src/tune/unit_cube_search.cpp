#include "bgkmap/tune/unit_cube_search.hpp"

#include <nlopt.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <stdexcept>

namespace bgkmap::tune {

namespace {

using Clock = std::chrono::steady_clock;

struct SearchState {
  const UnitObjective& f;
  const SearchBudget& budget;
  Clock::time_point started;
  SearchResult result;
  std::exception_ptr error;

  bool spent() const {
    const double elapsed = std::chrono::duration<double>(Clock::now() - started).count();
    return result.evaluations >= budget.evaluations || (budget.seconds > 0 && elapsed >= budget.seconds);
  }
  double evaluate(const std::vector<double>& x, const std::string& phase) {
    double v = f(x, phase);
    if (!std::isfinite(v)) v = std::numeric_limits<double>::max();
    ++result.evaluations;
    if (result.best.empty() || v < result.value) {
      result.best = x;
      result.value = v;
    }
    return v;
  }
};

struct Step {
  SearchState* state;
  nlopt::opt* opt;
  const char* phase;
};

double step_objective(const std::vector<double>& x, std::vector<double>& /*gradient*/, void* data) {
  Step& step = *static_cast<Step*>(data);
  if (step.state->spent()) {
    step.opt->force_stop();
    return step.state->result.value;
  }
  try {
    return step.state->evaluate(x, step.phase);
  } catch (...) {
    step.state->error = std::current_exception();
    step.opt->force_stop();
    return step.state->result.value;
  }
}

void run_step(SearchState& state, nlopt::algorithm algorithm, size_t evaluations, std::vector<double> x,
              const char* phase) {
  if (evaluations == 0 || state.spent()) return;
  nlopt::opt opt(algorithm, static_cast<unsigned>(x.size()));
  opt.set_lower_bounds(std::vector<double>(x.size(), 0.0));
  opt.set_upper_bounds(std::vector<double>(x.size(), 1.0));
  opt.set_maxeval(static_cast<int>(evaluations));
  if (algorithm == nlopt::LN_BOBYQA) {
    opt.set_initial_step(state.budget.local_step);
    opt.set_xtol_abs(state.budget.local_tolerance);
  }
  Step step{&state, &opt, phase};
  opt.set_min_objective(step_objective, &step);
  double value = 0;
  try {
    opt.optimize(x, value);
  } catch (const std::runtime_error&) {
    // forced stops (budget, time, an error kept in state.error) and round-off limits: the best point stands
  }
  if (state.error) std::rethrow_exception(state.error);
}

}  // namespace

SearchResult minimise_in_unit_cube(const UnitObjective& f, const std::vector<double>& start, const SearchBudget& budget) {
  if (start.empty()) throw std::invalid_argument("nothing to search: no parameter");
  std::vector<double> x0 = start;
  for (double& v : x0) v = std::clamp(v, 0.0, 1.0);
  SearchState state{f, budget, Clock::now(), {}, nullptr};
  state.evaluate(x0, "start");
  const size_t rest = budget.evaluations > 1 ? budget.evaluations - 1 : 0;
  // BOBYQA needs 2n + 1 points to build its first model: without room for two models, all is global.
  const size_t local_need = 2 * x0.size() + 1;
  const size_t global =
      rest >= 2 * local_need ? static_cast<size_t>(std::llround(budget.global_share * double(rest))) : rest;
  run_step(state, nlopt::GN_DIRECT_L, global, x0, "global");
  const size_t left = budget.evaluations - std::min(budget.evaluations, state.result.evaluations);
  if (left >= local_need) run_step(state, nlopt::LN_BOBYQA, left, state.result.best, "local");
  return state.result;
}

}  // namespace bgkmap::tune
