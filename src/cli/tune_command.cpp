// bgkmap tune: chooses a method's parameters by the likelihood of held-out beams or scans
// (src/tune), writes them as a YAML that build --config and eval --config take, and reports the
// trials and the scores of the given and the chosen parameters on both held-out splits.
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/tune/objective_plot.hpp"
#include "bgkmap/tune/tune.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/finite_number.hpp"
#include "cli/output_names.hpp"
#include "cli/tune_yaml.hpp"
#include "core/number_text.hpp"

namespace bgkmap::cli {

namespace {

struct TuneRequest {
  std::vector<std::string> inputs;
  std::string output, report, plot;
  double holdout = 0.1;
  std::string split = "beams";
  size_t run_length = 10;
  uint64_t seed = 1;
  double spacing = 0;
  std::string objective = "nll";
  size_t budget = 0;
  double seconds = 0;
  double search_scans = 0;
  bool quiet = false;
  BuildOptions options;
};

std::string values_text(const std::vector<std::string>& names, const std::vector<double>& values) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i] + " " + number_text(values[i]);
  return out;
}

std::string scores_text(const eval::BinaryMetrics& m) {
  char text[96];
  std::snprintf(text, sizeof text, "NLL %.4f  AUC %.4f", m.nll, m.auc);
  return text;
}

nlohmann::json metrics_json(const eval::BinaryMetrics& m) {
  const auto number = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); };
  return {{"nll", number(m.nll)},         {"auc", number(m.auc)},
          {"average_precision", number(m.average_precision)}, {"accuracy", number(m.accuracy)},
          {"n_positive", m.n_positive},   {"n_negative", m.n_negative}};
}

nlohmann::json values_json(const std::vector<std::string>& names, const std::vector<double>& values) {
  nlohmann::json out = nlohmann::json::object();
  for (size_t i = 0; i < names.size(); ++i) out[names[i]] = values[i];
  return out;
}

nlohmann::json report_json(const TuneRequest& req, const tune::TuneOptions& options, const tune::TuneResult& r) {
  nlohmann::json params = nlohmann::json::array();
  const std::vector<tune::TunableParam>& table = tune::tunable_params(options.method);
  for (size_t i = 0; i < r.names.size(); ++i)
    params.push_back({{"name", r.names[i]},
                      {"range", {r.ranges[i].lo, r.ranges[i].hi}},
                      {"scale", table[i].log_scale ? "log" : "linear"},
                      {"rebuilt", !table[i].from_sums},
                      {"given", r.defaults[i]},
                      {"chosen", r.chosen[i]}});
  nlohmann::json trials = nlohmann::json::array();
  for (const tune::Trial& t : r.trials) {
    nlohmann::json entry = {{"index", t.index}, {"phase", t.phase}, {"values", values_json(r.names, t.values)},
                            {"seconds", t.seconds}};
    if (t.error.empty()) {
      entry["objective"] = t.objective;
      entry["search"] = metrics_json(t.metrics);
    } else {
      entry["error"] = t.error;
    }
    trials.push_back(entry);
  }
  return {{"method", options.method},
          {"objective", req.objective},
          {"holdout",
           {{"split", req.split}, {"fraction", req.holdout}, {"seed", req.seed}, {"run_length", req.run_length},
            {"free_sample_spacing_m", options.spacing > 0 ? options.spacing : options.params.grid.resolution_m}}},
          {"scans", {{"all", r.scans}, {"training", r.training_scans}, {"search_training", r.search_training_scans}}},
          {"parameters", params},
          {"kept_given", r.kept_given},
          {"trials", trials},
          {"given", {{"search", metrics_json(r.given_scores.search)}, {"confirm", metrics_json(r.given_scores.confirm)}}},
          {"tuned", {{"search", metrics_json(r.tuned_scores.search)}, {"confirm", metrics_json(r.tuned_scores.confirm)}}},
          {"seconds", {{"tune", r.seconds}, {"given_build", r.given_build_s}}}};
}

std::vector<Scan> read_scans(const TuneRequest& req, const BuildParams& params) {
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.options.resolve_source());
  check_one_pose_uncertainty(params.preprocess, source);
  std::vector<Scan> scans;
  for (Scan scan; source.next(scan); scan = Scan{}) scans.push_back(std::move(scan));
  return scans;
}

tune::TuneOptions tune_options(const TuneRequest& req) {
  tune::TuneOptions o;
  o.method = req.options.method();
  tune::tunable_params(o.method);  // an untunable method is refused before the scans are read
  o.params = req.options.resolve_params();
  req.options.check_method_flags_read_by({o.method});
  o.method_params = req.options.resolve_method_params();
  o.backend = req.options.resolve_backend();
  o.split = {req.holdout, req.split == "scans" ? tune::SplitKind::kScans : tune::SplitKind::kBeams, req.run_length,
             req.seed};
  o.spacing = req.spacing;
  o.objective = req.objective == "auc" ? tune::Objective::kAuc : tune::Objective::kNll;
  o.budget = req.budget;
  o.seconds = req.seconds;
  o.search_scans = req.search_scans;
  if (!req.quiet)
    o.on_trial = [names = tune::tunable_params(o.method)](const tune::Trial& t) {
      std::vector<std::string> keys;
      for (const tune::TunableParam& p : names) keys.push_back(p.name);
      const std::string result = t.error.empty() ? scores_text(t.metrics) : "failed: " + t.error;
      std::fprintf(stderr, "bgkmap: trial %zu (%s): %s: %s (%.1f s)\n", t.index, t.phase.c_str(),
                   values_text(keys, t.values).c_str(), result.c_str(), t.seconds);
    };
  return o;
}

void print_summary(const tune::TuneOptions& o, const tune::TuneResult& r, const std::string& output) {
  std::fprintf(stderr, "bgkmap: given: search split %s, confirming split %s\n", scores_text(r.given_scores.search).c_str(),
               scores_text(r.given_scores.confirm).c_str());
  std::fprintf(stderr, "bgkmap: tuned: search split %s, confirming split %s\n", scores_text(r.tuned_scores.search).c_str(),
               scores_text(r.tuned_scores.confirm).c_str());
  std::fprintf(stderr, "bgkmap: wrote %s (%s): %zu trials in %.1f s; one build of the given parameters %.1f s\n",
               output.c_str(), values_text(r.names, r.chosen).c_str(), r.trials.size(), r.seconds, r.given_build_s);
  if (r.kept_given)
    std::fprintf(stderr, "bgkmap: kept the given parameters: the best trial scored worse than them on the search split "
                         "once built on every training scan (a --search-scans subset chose it)\n");
  if (tune::objective_value(r.tuned_scores.confirm, o.objective) > tune::objective_value(r.given_scores.confirm, o.objective))
    std::fprintf(stderr, "bgkmap: warning: the chosen parameters score worse than the given ones on the confirming "
                         "split: they fit the search split only (try more scans or a larger --holdout)\n");
}

void run_tune(const TuneRequest& req) {
  check_output_path(req.output);
  if (!req.report.empty()) check_output_path(req.report);
  if (!req.plot.empty()) check_output_path(req.plot);
  std::vector<NamedPath> outputs = {{"-o", req.output}};
  if (!req.report.empty()) outputs.push_back({"--report", req.report});
  if (!req.plot.empty()) outputs.push_back({"--plot", req.plot});
  std::vector<NamedPath> inputs;
  for (const std::string& in : req.inputs) inputs.push_back({"input", in});
  check_outputs_apart(outputs, inputs);
  const tune::TuneOptions options = tune_options(req);
  const tune::TuneResult result = tune::tune(read_scans(req, options.params), options);
  const std::string how = req.split == "scans" ? "held-out scans" : "held-out beams";
  const std::vector<std::string> comments = {
      "bgkmap tune --method " + options.method + ": " + how + " (fraction " + number_text(req.holdout) + ", seed " +
          std::to_string(req.seed) + "), objective " + req.objective,
      "chosen: " + values_text(result.names, result.chosen)};
  OutputBatch batch;
  write_file_atomically(req.output, [&](std::ostream& out) {
    out << tuned_config_yaml(options.method, result.params, result.method_params, comments);
  });
  if (!req.report.empty())
    write_file_atomically(req.report, [&](std::ostream& out) { out << report_json(req, options, result).dump(2) << '\n'; });
  if (!req.plot.empty()) tune::write_objective_plot(req.plot, options.method, result, options.objective);
  batch.commit();
  if (!req.quiet) print_summary(options, result, req.output);
}

}  // namespace

void add_tune_command(CLI::App& app) {
  auto req = std::make_shared<TuneRequest>();
  CLI::App* cmd = app.add_subcommand(
      "tune", "Choose a method's parameters by the likelihood of held-out beams or scans; "
              "writes a YAML for build --config");
  cmd->add_option("inputs", req->inputs, "Scan files or folders, as build takes them")->required();
  cmd->add_option("-o,--output", req->output, "Write the chosen parameters here (.yaml or .yml)")
      ->required()
      ->check(output_extension({".yaml", ".yml"}, "tune writes a YAML file of parameters"));
  cmd->add_option("--report", req->report, "Write the trials and the scores as JSON here");
  cmd->add_option("--plot", req->plot, "Draw each trial's objective against every tuned parameter here (.png)")
      ->check(output_extension({".png"}, "tune draws its trials as a PNG picture"));
  const CLI::Validator below_half(
      [](std::string& text) {
        double v = 0;
        try {
          v = std::stod(text);
        } catch (const std::exception&) {
          return std::string("not a number");
        }
        return v > 0 && v < 0.5 ? std::string() : std::string("must be in (0, 0.5)");
      },
      "in (0, 0.5)");
  cmd->add_option("--holdout", req->holdout,
                  "Fraction of the beams (or scans) the search scores on; as much again, disjoint, confirms the choice")
      ->check(below_half)
      ->capture_default_str();
  cmd->add_option("--split", req->split, "Hold out each scan's beams at random (beams) or whole scans in runs (scans)")
      ->check(CLI::IsMember({"beams", "scans"}))
      ->capture_default_str();
  cmd->add_option("--run-length", req->run_length, "With --split scans: consecutive scans per held-out run")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--seed", req->seed, "Seed of the held-out splits")->capture_default_str();
  cmd->add_option("--spacing", req->spacing, "Free samples along held-out beams every this many metres (default: the resolution)")
      ->check(CLI::PositiveNumber & finite_number("--spacing", "spacing", "METRES"));
  cmd->add_option("--objective", req->objective, "Minimise the held-out NLL (nll) or maximise the AUC (auc)")
      ->check(CLI::IsMember({"nll", "auc"}))
      ->capture_default_str();
  cmd->add_option("--budget", req->budget, "Map builds in the search, the given values' included (default 10 for bgkl, 24 for the others)")
      ->check(CLI::Range(size_t(1), size_t(10000)));
  cmd->add_option("--time", req->seconds, "Start no search build after this many seconds (the result then depends on the machine's speed)")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--search-scans", req->search_scans,
                  "Build the search's maps on this many training scans (a count >= 1, or a fraction below 1), evenly spread; "
                  "the given and the chosen parameters are then scored on maps of every training scan (default: all)")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("-q,--quiet", req->quiet, "No trials or summary");
  req->options.add_to(*cmd);
  cmd->callback([req] { run_tune(*req); });
}

}  // namespace bgkmap::cli
