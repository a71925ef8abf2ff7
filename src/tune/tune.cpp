#include "bgkmap/tune/tune.hpp"

#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>

#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/tune/prior_search.hpp"
#include "bgkmap/tune/prior_sums.hpp"
#include "bgkmap/tune/unit_cube_search.hpp"

namespace bgkmap::tune {

namespace {

using Clock = std::chrono::steady_clock;

double since(Clock::time_point t) { return std::chrono::duration<double>(Clock::now() - t).count(); }

struct Context {
  const TuneOptions& options;
  const std::vector<TunableParam>& table;
  std::vector<Range> ranges;
  std::vector<size_t> rebuilt, from_sums;  // indices into table
  std::vector<Scan> training, search_training;
  eval::LabelledPoints search_points, confirm_points;
};

double occupied_threshold(const std::string& method, const BuildParams& params) {
  // OctoMap's tree classifies by its own occupancy threshold; the others by --occupied-threshold.
  return method == "octomap" ? eval::octomap_default_occupied_threshold() : params.classify.occupied_threshold;
}

std::unique_ptr<MappingMethod> build(const Context& c, const BuildParams& p, const MethodParams& m,
                                     const std::vector<Scan>& scans) {
  std::unique_ptr<MappingMethod> method = make_method(c.options.method, p, m, c.options.backend);
  for (const Scan& scan : scans) method->insert(scan);
  method->finish();
  return method;
}

eval::BinaryMetrics score(MappingMethod& method, const eval::LabelledPoints& points, double threshold) {
  const eval::PointScore at = [&method](double x, double y, double z) {
    return method.occupancy(x, y, z).value_or(eval::kUnknownScore);
  };
  return eval::compute_metrics(eval::score_points(points, at), threshold);
}

PosteriorAt posterior_of(MappingMethod& method) {
  return [&method](double x, double y, double z) {
    const std::optional<CellEstimate> e = method.estimate(x, y, method.query_z(z));
    return e && e->beta ? *e->beta : CellPosterior{};
  };
}

std::vector<double> values_of(const Context& c, const BuildParams& p, const MethodParams& m) {
  std::vector<double> v;
  for (const TunableParam& t : c.table) v.push_back(t.get(p, m));
  return v;
}

// Sets the parameters `indices` from their unit coordinates.
void set_from_unit(const Context& c, const std::vector<size_t>& indices, const std::vector<double>& u, BuildParams& p,
                   MethodParams& m) {
  for (size_t k = 0; k < indices.size(); ++k) {
    const size_t i = indices[k];
    c.table[i].set(p, m, from_unit(c.table[i].log_scale, c.ranges[i], u[k]));
  }
}

std::vector<double> unit_of(const Context& c, const std::vector<size_t>& indices, const BuildParams& p,
                            const MethodParams& m) {
  std::vector<double> u;
  for (size_t i : indices) u.push_back(to_unit(c.table[i].log_scale, c.ranges[i], c.table[i].get(p, m)));
  return u;
}

// A Beta method's prior (the from_sums parameters, alpha0 then beta0) that scores best on one
// build's sums, set in `p`; returns its metrics.
eval::BinaryMetrics choose_prior(const Context& c, const HeldOutSums& sums, BuildParams& p) {
  p.prior = best_prior(sums, p.kernel.sigma0, p.prior, c.ranges[c.from_sums[0]], c.ranges[c.from_sums[1]],
                       c.options.objective);
  return eval::compute_metrics(scores_from_sums(sums, p.kernel.sigma0, p.prior.alpha0, p.prior.beta0),
                               occupied_threshold(c.options.method, p));
}

// One trial's build and score at the rebuilt parameters' unit coordinates `u`; `p` and `m` get
// the trial's values (BGK-L: the prior chosen for it too).
Trial run_trial(const Context& c, const std::vector<double>& u, BuildParams& p, MethodParams& m) {
  const Clock::time_point start = Clock::now();
  Trial trial;
  set_from_unit(c, c.rebuilt, u, p, m);
  try {
    p.validate();
    m.validate();
    std::unique_ptr<MappingMethod> method = build(c, p, m, c.search_training);
    if (c.from_sums.empty()) {
      trial.metrics = score(*method, c.search_points, occupied_threshold(c.options.method, p));
    } else {
      const HeldOutSums sums = held_out_sums(c.search_points, posterior_of(*method), p.kernel.sigma0, p.prior.alpha0,
                                             p.prior.beta0);
      trial.metrics = choose_prior(c, sums, p);
    }
    trial.objective = objective_value(trial.metrics, c.options.objective);
  } catch (const std::invalid_argument& e) {
    trial.error = e.what();
  } catch (const std::runtime_error& e) {  // e.g. a GP's kernel matrix not positive definite
    trial.error = e.what();
  }
  if (!trial.error.empty() || !std::isfinite(trial.objective)) trial.objective = std::numeric_limits<double>::max();
  trial.values = values_of(c, p, m);
  trial.seconds = since(start);
  return trial;
}

size_t search_scan_count(double search_scans, size_t training) {
  if (!(search_scans >= 0) || !std::isfinite(search_scans))
    throw std::invalid_argument("the search's scans must be a fraction in (0, 1) or a count >= 1");
  if (search_scans == 0) return training;
  if (search_scans < 1) return std::max<size_t>(1, static_cast<size_t>(std::llround(search_scans * double(training))));
  return search_scans >= double(training) ? training : static_cast<size_t>(search_scans);  // no cast of a huge double
}

Context make_context(std::vector<Scan> scans, const TuneOptions& o, TuneResult& result) {
  Context c{o, tunable_params(o.method), {}, {}, {}, {}, {}, {}, {}};
  for (size_t i = 0; i < c.table.size(); ++i) {
    c.ranges.push_back(absolute_range(c.table[i], o.params));
    (c.table[i].from_sums ? c.from_sums : c.rebuilt).push_back(i);
  }
  result.scans = scans.size();
  TuneSplit split = split_for_tuning(std::move(scans), o.split);
  const double spacing = o.spacing > 0 ? o.spacing : o.params.grid.resolution_m;
  c.search_points = eval::holdout_points(split.search, o.params.preprocess, spacing);
  c.confirm_points = eval::holdout_points(split.confirm, o.params.preprocess, spacing);
  for (const eval::LabelledPoints* points : {&c.search_points, &c.confirm_points})
    if (points->occupied.empty() || points->free.empty())
      throw std::invalid_argument("a held-out split has no occupied or no free sample: give more scans or a larger held-out fraction");
  c.training = std::move(split.training);
  c.search_training = spread_subset(c.training, search_scan_count(o.search_scans, c.training.size()));
  result.training_scans = c.training.size();
  result.search_training_scans = c.search_training.size();
  result.search_held_scans = o.split.kind == SplitKind::kScans ? split.search.size() : 0;
  result.confirm_held_scans = o.split.kind == SplitKind::kScans ? split.confirm.size() : 0;
  return c;
}

// The search: trials in order, the best one's parameters set in result.params / method_params.
void search(const Context& c, TuneResult& result, double seconds_left) {
  const TuneOptions& o = c.options;
  std::map<std::vector<double>, size_t> seen;  // rebuilt values (as the build takes them) -> trial
  std::optional<size_t> best;
  BuildParams inner_start = o.params;  // BGK-L: each trial's prior search starts at the best prior so far
  const UnitObjective f = [&](const std::vector<double>& u, const std::string& phase) {
    BuildParams p = inner_start;
    MethodParams m = o.method_params;
    set_from_unit(c, c.rebuilt, u, p, m);
    std::vector<double> key;
    for (size_t i : c.rebuilt) key.push_back(c.table[i].get(p, m));
    if (const auto it = seen.find(key); it != seen.end()) return result.trials[it->second].objective;
    Trial trial = run_trial(c, u, p, m);
    trial.index = result.trials.size();
    trial.phase = phase;
    seen[key] = trial.index;
    if (!best || trial.objective < result.trials[*best].objective) {
      best = trial.index;
      result.params = p;
      result.method_params = m;
      inner_start.prior = p.prior;
    }
    if (o.on_trial) o.on_trial(trial);
    result.trials.push_back(trial);
    return trial.objective;
  };
  SearchBudget budget;
  budget.evaluations = o.budget > 0 ? o.budget : default_budget(o.method);
  budget.seconds = seconds_left;
  if (c.rebuilt.empty())
    f({}, "start");  // counting: the prior alone, chosen from one build's sums
  else
    minimise_in_unit_cube(f, unit_of(c, c.rebuilt, o.params, o.method_params), budget);
  if (!best || !result.trials[*best].error.empty())
    throw std::runtime_error("no trial's build succeeded" +
                             (result.trials.empty() ? std::string() : ": " + result.trials.front().error));
}

// The given and the chosen parameters built on every training scan, each scored on both splits.
SplitScores confirm(const Context& c, const BuildParams& p, const MethodParams& m, double* seconds) {
  const Clock::time_point start = Clock::now();
  std::unique_ptr<MappingMethod> method = build(c, p, m, c.training);
  if (seconds) *seconds = since(start);
  const double threshold = occupied_threshold(c.options.method, p);
  return {score(*method, c.search_points, threshold), score(*method, c.confirm_points, threshold)};
}

}  // namespace

size_t default_budget(const std::string& method) { return method == "bgkl" ? 10 : 24; }

TuneResult tune(std::vector<Scan> scans, const TuneOptions& options) {
  const Clock::time_point start = Clock::now();
  options.params.validate();
  options.method_params.validate();
  if (!(options.seconds >= 0) || !std::isfinite(options.seconds))
    throw std::invalid_argument("the search's time must be a number of seconds >= 0");
  TuneResult result;
  const Context c = make_context(std::move(scans), options, result);
  for (const TunableParam& t : c.table) result.names.push_back(t.name);
  result.ranges = c.ranges;
  result.defaults = values_of(c, options.params, options.method_params);
  const double left = options.seconds > 0 ? std::max(1e-9, options.seconds - since(start)) : 0;
  search(c, result, left);
  result.given_scores = confirm(c, options.params, options.method_params, &result.given_build_s);
  result.tuned_scores = confirm(c, result.params, result.method_params, nullptr);
  // A choice made on a subset of the scans can lose to the given values once every scan is in the
  // map (sparser maps want longer kernels); the search split decides, the confirming one stays unseen.
  if (objective_value(result.tuned_scores.search, options.objective) >
      objective_value(result.given_scores.search, options.objective)) {
    result.kept_given = true;
    result.params = options.params;
    result.method_params = options.method_params;
    result.tuned_scores = result.given_scores;
  }
  result.chosen = values_of(c, result.params, result.method_params);
  result.seconds = since(start);
  return result;
}

}  // namespace bgkmap::tune
