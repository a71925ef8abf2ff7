// bgkmap eval: scores maps of any method (.bgk, .ot, .bt) against analytic truth (scene.yaml or a
// truth .bt), or builds maps with one or several methods on part of each scan's beams and scores
// them on the held-out ones; writes the metrics as JSON and the figures as PNG.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/eval/dynamic_cells.hpp"
#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/eval/plot.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/eval/truth.hpp"
#include "bgkmap/eval/update_sequence.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/sim/spec.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/finite_number.hpp"
#include "cli/progress.hpp"
#include "cli/output_names.hpp"
#include "core/number_text.hpp"

namespace bgkmap::cli {

namespace {

struct EvalRequest {
  std::vector<std::string> inputs;  // maps, or scans with --holdout
  std::string truth;
  std::string json;
  std::string plot;
  std::string title;  // of the --plot figure; empty: say what was scored
  std::string slice;
  double slice_z = NAN;
  double holdout = -1;
  uint64_t seed = 1;
  double spacing = 0;
  std::string split = "beams";  // or "scans": whole scans held out, in runs of run_length
  size_t run_length = 10;
  std::optional<int> truth_at;             // --truth-at: a dynamic scene's truth at this scan
  size_t per_scan = 0;                     // --per-scan K: build the scans, score every K of them
  std::string protocol;    // "bhm-table2": scored after each update (eval/update_sequence.hpp)
  uint64_t score_every = 1;
  std::vector<std::string> methods;        // --methods (holdout): several, on the same split
  BuildOptions options;                    // --holdout only
  CLI::Option* method_option = nullptr;    // BuildOptions' --method, to refuse it with --methods
  std::vector<CLI::Option*> build_flags;   // every option BuildOptions added, to refuse them with --truth
  ProgressFlags progress;
};

nlohmann::json metrics_json(const eval::BinaryMetrics& m) {
  // NaN (an undefined metric, e.g. precision with nothing predicted occupied) becomes null.
  return {{"auc", m.auc},         {"average_precision", m.average_precision},
          {"nll", m.nll},         {"accuracy", m.accuracy},
          {"precision", m.precision}, {"recall", m.recall},
          {"n_positive", m.n_positive}, {"n_negative", m.n_negative}};
}

nlohmann::json box_json(const sim::Box3d& b) {
  return {{"min", {b.min.x, b.min.y, b.min.z}}, {"max", {b.max.x, b.max.y, b.max.z}}};
}

std::string box_text(const sim::Box3d& b) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "[%.2f %.2f %.2f .. %.2f %.2f %.2f]", b.min.x, b.min.y, b.min.z, b.max.x, b.max.y,
                b.max.z);
  return buf;
}

std::string metres(double v) { return number_text(v) + " m"; }

sim::Box3d intersect(const sim::Box3d& a, const sim::Box3d& b) {
  return {{std::max(a.min.x, b.min.x), std::max(a.min.y, b.min.y), std::max(a.min.z, b.min.z)},
          {std::min(a.max.x, b.max.x), std::min(a.max.y, b.max.y), std::min(a.max.z, b.max.z)}};
}

void write_json(const std::string& file, nlohmann::json report) {
  write_file_atomically(file, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
}

void print_summary(const EvalRequest& req, const std::string& name, const eval::BinaryMetrics& m) {
  if (req.progress.quiet) return;
  std::fprintf(stderr, "bgkmap: %s: AUC %.4f  AP %.4f  NLL %.4f  accuracy %.4f  (%llu occupied, %llu free)\n",
               name.c_str(), m.auc, m.average_precision, m.nll, m.accuracy,
               static_cast<unsigned long long>(m.n_positive), static_cast<unsigned long long>(m.n_negative));
}

bool is_empty(const sim::Box3d& b) { return b.min.x > b.max.x || b.min.y > b.max.y || b.min.z > b.max.z; }

nlohmann::json vacated_json(const eval::VacatedScores& v) {
  const auto fraction = [](uint64_t part, uint64_t whole) { return whole > 0 ? double(part) / whole : NAN; };
  return {{"cells", v.cells},
          {"read_free", fraction(v.read_free, v.cells)},
          {"read_occupied", fraction(v.read_occupied, v.cells)},
          {"settled_cells", v.settled_cells},
          {"settled_read_free", fraction(v.settled_free, v.settled_cells)}};
}

bool is_scene_file(const std::string& file) {
  const std::string ext = std::filesystem::path(file).extension().string();
  return ext == ".yaml" || ext == ".yml";
}

// A dynamic scene's scores at time `scan` (dynamic_cells.hpp): the static cells' metrics over
// `box` and the vacated cells'; `dynamic` has taken scans 0..scan into account.
nlohmann::json dynamic_json(const eval::MapSampler& sample, const Grid& grid, const eval::Truth& truth,
                            const eval::DynamicCells& dynamic, const sim::Box3d& box, double free_threshold,
                            double occupied_threshold) {
  const std::unique_ptr<eval::Truth> static_truth = eval::static_cells_truth(truth, dynamic);
  const eval::TruthScores scores = eval::score_against_truth(sample, grid, *static_truth, box);
  const eval::DynamicScores vacated = dynamic.score(sample, free_threshold, occupied_threshold);
  return {{"scan", dynamic.next_scan() - 1},
          {"static_cells", {{"all_cells", metrics_json(eval::compute_metrics(scores.all_cells, occupied_threshold))},
                            {"observed_cells",
                             metrics_json(eval::compute_metrics(scores.observed_cells, occupied_threshold))}}},
          {"removed_cells", vacated_json(vacated.removed)},
          {"trail_cells", vacated_json(vacated.trail)}};
}

// A scene file's spec when it has dynamic objects.
std::optional<sim::SimulationSpec> dynamic_spec(const std::string& truth) {
  if (!is_scene_file(truth)) return std::nullopt;
  sim::SimulationSpec spec = sim::load_spec(truth);
  if (spec.scene.dynamic.empty()) return std::nullopt;
  return spec;
}

void run_truth_eval(const EvalRequest& req, ProgressBar& progress) {
  std::vector<std::unique_ptr<eval::ScoredMap>> maps;
  for (const std::string& file : req.inputs) {
    maps.push_back(eval::load_scored_map(file));
    if (maps.back()->is_classified_tree())
      throw InputError(file, "holds only the cells its map classified occupied or free (--ot-values classified), "
                             "so the others would score as unknown; score the .bgk, or a .ot built with "
                             "--ot-values mean");
    const double r0 = maps.front()->resolution(), r = maps.back()->resolution();
    if (std::abs(r - r0) > 1e-9 * r0)
      throw InputError(file, "resolution " + metres(r) + " differs from " + req.inputs.front() + "'s " + metres(r0) +
                                 "; maps scored together must share one grid");
  }
  const std::unique_ptr<eval::Truth> truth = eval::load_truth(req.truth, maps.front()->grid(), req.truth_at);
  const std::optional<sim::SimulationSpec> dynamic = dynamic_spec(req.truth);
  std::optional<eval::DynamicCells> cells;
  if (dynamic) {
    cells.emplace(*dynamic, maps.front()->grid());
    while (cells->next_scan() <= req.truth_at.value_or(dynamic->trajectory.scans - 1)) cells->advance();
  }

  // One box for every map, so that the all-cells protocol scores each map on the same cells.
  sim::Box3d observed = sim::Box3d::empty();
  for (const auto& map : maps) {
    const sim::Box3d bounds = map->observed_bounds();
    if (!is_empty(bounds)) observed.expand(bounds);
  }
  if (is_empty(observed))
    throw InputError(req.inputs.front(), maps.size() == 1 ? "the map has no cell with evidence"
                                                          : "none of the maps has a cell with evidence");
  const sim::Box3d region = truth->region();
  if (!region.overlaps(observed))
    throw InputError(req.truth, "truth region " + box_text(region) + " does not overlap the maps' observed bounds " +
                                    box_text(observed) + " (a different frame?)");
  const sim::Box3d box = intersect(region, observed);

  nlohmann::json report = {{"mode", "truth"}, {"truth", req.truth}, {"evaluated_box", box_json(box)},
                           {"primary_protocol", "all_cells"}, {"unknown_score", eval::kUnknownScore}};
  nlohmann::json per_map = nlohmann::json::array();
  std::vector<eval::CurveSeries> series;
  for (size_t i = 0; i < maps.size(); ++i) {
    const std::string phase = "score " + std::filesystem::path(req.inputs[i]).filename().string();
    const eval::TruthScores scores = eval::score_against_truth(*maps[i], *truth, box, [&](Progress p) {
      p.phase = phase;
      progress.report(p);
    });
    progress.finish();
    const double threshold = maps[i]->occupied_threshold();
    const eval::BinaryMetrics all = eval::compute_metrics(scores.all_cells, threshold);
    const eval::BinaryMetrics seen = eval::compute_metrics(scores.observed_cells, threshold);
    nlohmann::json entry = metrics_json(all);
    entry["map"] = req.inputs[i];
    entry["occupied_threshold"] = threshold;
    entry["protocols"] = {{"all_cells", metrics_json(all)}, {"observed_cells", metrics_json(seen)}};
    if (cells) {
      const eval::ScoredMap& map = *maps[i];
      entry["dynamic"] = dynamic_json([&map](const Vec3d& p) { return map.sample(p.x, p.y, p.z); }, map.grid(),
                                      *truth, *cells, box, map.free_threshold(), threshold);
    }
    per_map.push_back(entry);
    print_summary(req, req.inputs[i] + " (all cells)", all);
    print_summary(req, req.inputs[i] + " (observed cells)", seen);
    if (!req.plot.empty()) {
      // One colour per map: all cells solid, observed cells dashed.
      const std::string label = std::filesystem::path(req.inputs[i]).filename().string();
      const int colour = static_cast<int>(i);
      series.push_back({label + " all cells", eval::compute_curves(scores.all_cells), all.auc, all.average_precision,
                        colour, false});
      series.push_back({label + " observed cells", eval::compute_curves(scores.observed_cells), seen.auc,
                        seen.average_precision, colour, true});
    }
  }
  if (maps.size() == 1) report.update(per_map[0]);  // a single map's metrics are the top-level keys
  report["maps"] = per_map;
  write_json(req.json, report);
  if (!req.plot.empty())
    eval::write_curves_png(req.plot, series,
                           req.title.empty()
                               ? "Scored against the truth in " + std::filesystem::path(req.truth).filename().string()
                               : req.title);
  if (!req.slice.empty()) {
    const std::optional<double> busiest = std::isnan(req.slice_z) ? eval::busiest_layer_z(*maps.front()) : std::nullopt;
    const double z = !std::isnan(req.slice_z) ? req.slice_z : busiest ? *busiest : 0.5 * (box.min.z + box.max.z);
    const eval::SliceImage slice = eval::make_slice(*maps.front(), truth.get(), box, z);
    eval::write_slice_png(req.slice, slice, std::filesystem::path(req.inputs.front()).filename().string());
  }
}

// The methods --method / --methods name, in order.
std::vector<std::string> holdout_methods(const EvalRequest& req) {
  if (req.methods.empty()) return {req.options.method()};
  if (req.method_option && req.method_option->count() > 0)
    throw std::invalid_argument("give --method or --methods, not both");
  return req.methods;
}

struct HoldoutSplitCounts {
  uint64_t scans = 0, held_scans = 0, kept_beams = 0, held_beams = 0;
};

// Inserts the training data of every scan into `method` (the split is the same on every pass):
// with --split beams the kept beams of each scan, with --split scans the scans not held out
// (`held_scans`, from split_scans). When `held_out` is given, collects the held-out beams (points only).
HoldoutSplitCounts build_on_training_data(const EvalRequest& req, const std::vector<bool>& held_scans,
                                          MappingMethod& method, std::vector<Scan>* held_out, ProgressBar& progress) {
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.options.resolve_source());
  method.set_progress(progress.callback());
  check_one_pose_uncertainty(method.params().preprocess, source);
  HoldoutSplitCounts counts;
  Scan scan;
  const std::string phase = "build " + method.name();
  for (uint64_t index = 0; source.next(scan); ++index) {
    progress.report(scan_progress(phase, source.progress()));
    ++counts.scans;
    if (req.split == "scans") {
      if (index < held_scans.size() && held_scans[index]) {
        if (held_out) held_out->push_back(scan);
        ++counts.held_scans;
        counts.held_beams += scan.points.size();
      } else {
        method.insert(scan);
        counts.kept_beams += scan.points.size();
      }
      continue;
    }
    const eval::BeamSplit split = eval::split_beams(scan.points.size(), req.holdout, req.seed, index);
    method.insert(eval::select_beams(scan, split.kept));
    if (held_out) held_out->push_back(eval::select_beams(scan, split.held_out));
    counts.kept_beams += split.kept.size();
    counts.held_beams += split.held_out.size();
  }
  progress.report(scan_progress(phase, source.progress()));
  method.finish();
  progress.finish();
  return counts;
}

// With --split scans: which scans are held out (a first pass counts them).
std::vector<bool> held_out_scans(const EvalRequest& req, ProgressBar& progress) {
  if (req.split != "scans") return {};
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.options.resolve_source());
  size_t count = 0;
  for (Scan scan; source.next(scan); ++count) progress.report(scan_progress("count scans", source.progress()));
  progress.finish();
  return eval::split_scans(count, {req.holdout, req.run_length, req.seed});
}

void run_holdout_eval(const EvalRequest& req, ProgressBar& progress) {
  req.options.check_method_flags_read_by(holdout_methods(req));
  const BuildParams params = req.options.resolve_params();
  const MethodParams method_params = req.options.resolve_method_params();
  const BackendOptions backend_options = req.options.resolve_backend();
  // Every method is made up front, so that a bad name or parameter is refused before any build.
  std::vector<std::unique_ptr<MappingMethod>> methods;
  for (const std::string& name : holdout_methods(req))
    methods.push_back(make_method(name, params, method_params, backend_options));
  const double spacing = req.spacing > 0 ? req.spacing : params.grid.resolution_m;
  const std::vector<bool> held_scans = held_out_scans(req, progress);

  std::vector<Scan> held_out;  // scored after each whole map is built, so kept (points only)
  HoldoutSplitCounts split;
  nlohmann::json per_method = nlohmann::json::array();
  std::vector<eval::CurveSeries> series;
  for (std::unique_ptr<MappingMethod>& method : methods) {
    if (!method->backend().note.empty()) std::fprintf(stderr, "bgkmap: warning: %s\n", method->backend().note.c_str());
    const bool first = &method == &methods.front();
    split = build_on_training_data(req, held_scans, *method, first ? &held_out : nullptr, progress);
    eval::LabelledScores scores;
    const eval::PointScore score = [&method](double x, double y, double z) {
      return method->occupancy(x, y, z).value_or(eval::kUnknownScore);
    };
    for (size_t i = 0; i < held_out.size(); ++i) {
      progress.report({"score " + method->name(), "scans", i, held_out.size(), false});
      eval::add_holdout_samples(held_out[i], params.preprocess, spacing, score, scores);
    }
    progress.report({"score " + method->name(), "scans", held_out.size(), held_out.size(), false});
    progress.finish();
    // OctoMap's tree classifies by its own occupancy threshold; the BGK maps and GPOctoMap by --occupied-threshold.
    const double threshold = method->name() == "octomap" ? eval::octomap_default_occupied_threshold()
                                                         : params.classify.occupied_threshold;
    const eval::BinaryMetrics m = eval::compute_metrics(scores, threshold);
    nlohmann::json entry = metrics_json(m);
    entry["method"] = method->name();
    entry["occupied_threshold"] = threshold;
    entry["cells_with_evidence"] = method->known_cells();
    per_method.push_back(entry);
    print_summary(req, method->name() + (req.split == "scans" ? " on held-out scans" : " on held-out beams"), m);
    if (!req.plot.empty()) series.push_back({method->name(), eval::compute_curves(scores), m.auc, m.average_precision});
    method.reset();  // one map in memory at a time
  }

  nlohmann::json report = methods.size() == 1 ? per_method[0] : nlohmann::json::object();
  report["mode"] = "holdout";
  report["holdout"] = {{"split", req.split},
                       {"fraction", req.holdout},
                       {"seed", req.seed},
                       {"free_sample_spacing_m", spacing},
                       {"scans", split.scans},
                       {"kept_beams", split.kept_beams},
                       {"held_out_beams", split.held_beams}};
  if (req.split == "scans") {
    report["holdout"]["run_length"] = req.run_length;
    report["holdout"]["held_out_scans"] = split.held_scans;
  }
  report["unknown_score"] = eval::kUnknownScore;
  report["methods"] = per_method;
  write_json(req.json, report);
  if (!req.plot.empty()) {
    const std::string who = methods.size() == 1 ? per_method[0]["method"].get<std::string>()
                                                : std::to_string(methods.size()) + " methods";
    const std::string split_text =
        req.split == "scans" ? "held-out scans (fraction " + number_text(req.holdout) + " in runs of " +
                                   std::to_string(req.run_length) + ", seed " + std::to_string(req.seed) + ")"
                             : "held-out beams (fraction " + number_text(req.holdout) + ", seed " + std::to_string(req.seed) + ")";
    eval::write_curves_png(req.plot, series, req.title.empty() ? who + " on " + split_text : req.title + ": " + split_text);
  }
}

// One row of --per-scan: the method's map after scans 0..t against the truth at t.
nlohmann::json per_scan_row(MappingMethod& method, const sim::SimulationSpec& spec, const Grid& grid,
                            const eval::DynamicCells& cells, double free_threshold, double occupied_threshold) {
  const int t = cells.next_scan() - 1;
  const eval::MapSampler sample = [&method](const Vec3d& p) {
    return eval::sample_of_probability(method.occupancy(p.x, p.y, p.z));
  };
  const std::unique_ptr<eval::Truth> truth = eval::make_scene_truth(sim::scene_at(spec.scene, t), grid);
  const sim::Box3d box = truth->region();
  const eval::TruthScores scores = eval::score_against_truth(sample, grid, *truth, box);
  nlohmann::json row = dynamic_json(sample, grid, *truth, cells, box, free_threshold, occupied_threshold);
  row["all_cells"] = metrics_json(eval::compute_metrics(scores.all_cells, occupied_threshold));
  row["observed_cells"] = metrics_json(eval::compute_metrics(scores.observed_cells, occupied_threshold));
  return row;
}

// --per-scan K: the scans of a simulated scene built in order, scored after every K scans and the
// last against the scene at that time, over the whole truth region.
void run_per_scan_eval(const EvalRequest& req, ProgressBar& progress) {
  if (!is_scene_file(req.truth))
    throw InputError(req.truth, "--per-scan needs the scene file (.yaml) the scans were simulated from");
  const sim::SimulationSpec spec = sim::load_spec(req.truth);
  const BuildParams params = req.options.resolve_params();
  req.options.check_method_flags_read_by({req.options.method()});
  std::unique_ptr<MappingMethod> method =
      make_method(req.options.method(), params, req.options.resolve_method_params(), req.options.resolve_backend());
  const Grid grid(params.grid);
  eval::DynamicCells cells(spec, grid);
  const bool octomap = method->name() == "octomap";  // classifies by OctoMap's own threshold
  const double occupied = octomap ? eval::octomap_default_occupied_threshold() : params.classify.occupied_threshold;
  const double free = octomap ? occupied : params.classify.free_threshold;
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.options.resolve_source());
  method->set_progress(progress.callback());
  nlohmann::json rows = nlohmann::json::array();
  Scan scan;
  bool more = source.next(scan);
  while (more) {
    if (cells.next_scan() >= spec.trajectory.scans)
      throw InputError(req.truth, "the inputs hold more scans than the scene's " + std::to_string(spec.trajectory.scans));
    progress.report(scan_progress("build " + method->name(), source.progress()));
    method->insert(scan);
    cells.advance();
    more = source.next(scan);
    if (cells.next_scan() % req.per_scan != 0 && more) continue;
    method->finish();
    rows.push_back(per_scan_row(*method, spec, grid, cells, free, occupied));
  }
  progress.finish();
  if (rows.empty()) throw InputError(req.inputs.front(), "no scans");
  const nlohmann::json last = rows.back();
  if (!req.progress.quiet)
    std::fprintf(stderr, "bgkmap: %s after %d scans: static AUC %.4f, removed cells settled free %.3f, trail cells "
                         "occupied %.3f\n", method->name().c_str(), last["scan"].get<int>() + 1,
                 last["static_cells"]["all_cells"]["auc"].get<double>(),
                 last["removed_cells"]["settled_read_free"].is_number() ? last["removed_cells"]["settled_read_free"].get<double>() : NAN,
                 last["trail_cells"]["read_occupied"].is_number() ? last["trail_cells"]["read_occupied"].get<double>() : NAN);
  write_json(req.json, {{"mode", "per_scan"}, {"truth", req.truth}, {"method", method->name()},
                        {"every", req.per_scan}, {"occupied_threshold", occupied}, {"free_threshold", free},
                        {"settle_scans", eval::kSettleScans}, {"unknown_score", eval::kUnknownScore}, {"rows", rows}});
}

nlohmann::json mean_two_sigma_json(const eval::MeanTwoSigma& s) {
  return {{"mean", s.mean}, {"two_sigma", s.two_sigma}, {"updates", s.count}};
}

// --protocol bhm-table2: one method, updated scan by scan on each scan's kept beams and scored
// after every --score-every updates on the held-out beams of the scans so far.
void run_sequence_eval(const EvalRequest& req, ProgressBar& progress) {
  if (!req.methods.empty()) throw std::invalid_argument("--protocol bhm-table2 scores one --method, not --methods");
  if (req.split != "beams") throw std::invalid_argument("--protocol bhm-table2 holds out beams: --split scans is not its protocol");
  if (req.holdout != 0.1) throw std::invalid_argument("--protocol bhm-table2 holds out 10 % of the data: give --holdout 0.1 or none");
  const BuildParams params = req.options.resolve_params();
  req.options.check_method_flags_read_by({req.options.method()});
  const std::unique_ptr<MappingMethod> method =
      make_method(req.options.method(), params, req.options.resolve_method_params(), req.options.resolve_backend());
  if (!method->backend().note.empty()) std::fprintf(stderr, "bgkmap: warning: %s\n", method->backend().note.c_str());
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.options.resolve_source());
  method->set_progress(progress.callback());
  check_one_pose_uncertainty(method->params().preprocess, source);
  eval::UpdateSequenceParams p;
  p.fraction = req.holdout;
  p.seed = req.seed;
  p.spacing = req.spacing > 0 ? req.spacing : params.grid.resolution_m;
  p.every = req.score_every;
  p.occupied_threshold = method->name() == "octomap" ? eval::octomap_default_occupied_threshold()
                                                     : params.classify.occupied_threshold;
  p.preprocess = params.preprocess;
  const std::string phase = "build and score " + method->name();
  const eval::UpdateSequenceResult r = eval::run_update_sequence(
      [&](Scan& scan) {
        progress.report(scan_progress(phase, source.progress()));
        return source.next(scan);
      },
      [&](const Scan& kept) { method->insert(kept); },
      [&](double x, double y, double z) { return method->occupancy(x, y, z).value_or(eval::kUnknownScore); }, p);
  method->finish();
  progress.finish();
  nlohmann::json updates = nlohmann::json::array();
  for (const eval::UpdateScore& u : r.updates) {
    nlohmann::json entry = metrics_json(u.metrics);
    entry["scans"] = u.scans;
    updates.push_back(entry);
  }
  const nlohmann::json report = {
      {"mode", "protocol"},
      {"protocol", req.protocol},
      {"method", method->name()},
      {"auc", mean_two_sigma_json(r.auc)},
      {"nll", mean_two_sigma_json(r.nll)},
      {"holdout", {{"split", "beams"}, {"fraction", p.fraction}, {"seed", p.seed}, {"free_sample_spacing_m", p.spacing},
                   {"score_every", p.every}, {"scans", r.scans}, {"kept_beams", r.kept_beams}, {"held_out_beams", r.held_beams}}},
      {"unknown_score", eval::kUnknownScore},
      {"updates", updates}};
  write_json(req.json, report);
  if (!req.progress.quiet)
    std::fprintf(stderr, "bgkmap: %s, %s over %llu scored updates: AUC %.4f +- %.4f  NLL %.4f +- %.4f (mean +- 2 sigma)\n",
                 method->name().c_str(), req.protocol.c_str(), static_cast<unsigned long long>(r.auc.count), r.auc.mean,
                 r.auc.two_sigma, r.nll.mean, r.nll.two_sigma);
}

void run_eval(const EvalRequest& req) {
  if (!req.protocol.empty()) {
    if (!req.truth.empty()) throw std::invalid_argument("--protocol bhm-table2 scores held-out beams of scans, not maps against --truth");
    EvalRequest with_holdout = req;
    if (with_holdout.holdout < 0) with_holdout.holdout = 0.1;
    for (const std::string* out : {&req.json, &req.plot, &req.slice})
      if (!out->empty()) check_output_path(*out);
    if (!req.plot.empty() || !req.slice.empty()) throw std::invalid_argument("--protocol writes --json only");
    OutputBatch outputs;
    ProgressBar progress(req.progress);
    run_sequence_eval(with_holdout, progress);
    outputs.commit();
    return;
  }
  if (req.score_every != 1) throw std::invalid_argument("--score-every needs --protocol");
  const bool holdout = req.holdout >= 0;
  if (req.per_scan > 0 && (holdout || req.truth_at || !req.plot.empty() || !req.slice.empty() || !req.methods.empty()))
    throw std::invalid_argument("--per-scan builds the scans with --method and scores every step against --truth "
                                "SCENE.yaml: it goes without --holdout, --truth-at, --plot, --slice and --methods");
  if (holdout == !req.truth.empty())
    throw std::invalid_argument("eval needs exactly one of --truth SCENE_OR_BT (inputs are maps) or --holdout "
                                "FRACTION (inputs are scans)");
  if (holdout && !req.slice.empty()) throw std::invalid_argument("--slice needs --truth");
  if (!holdout && !req.methods.empty()) throw std::invalid_argument("--methods needs --holdout (with --truth, give the maps)");
  if (!holdout && (req.split != "beams" || req.run_length != 10))
    throw std::invalid_argument("--split and --run-length need --holdout");
  if (holdout && req.truth_at) throw std::invalid_argument("--truth-at needs --truth");
  if (!holdout && req.per_scan == 0)
    for (const CLI::Option* flag : req.build_flags)
      if (flag->count() > 0)
        throw std::invalid_argument(flag->get_name() + " is a build flag: with --truth the maps are scored as they "
                                    "were built (each with its own thresholds); it applies to --holdout runs");
  for (const std::string* out : {&req.json, &req.plot, &req.slice})
    if (!out->empty()) check_output_path(*out);
  // The metrics, plot and slice are renamed into place together once all are written.
  OutputBatch outputs;
  ProgressBar progress(req.progress);
  if (req.per_scan > 0)
    run_per_scan_eval(req, progress);
  else
    holdout ? run_holdout_eval(req, progress) : run_truth_eval(req, progress);
  outputs.commit();
}

}  // namespace

void add_eval_command(CLI::App& app) {
  auto req = std::make_shared<EvalRequest>();
  CLI::App* cmd = app.add_subcommand(
      "eval", "Score maps against truth (--truth scene.yaml or truth.bt) or on held-out beams or whole scans of the inputs (--holdout, --split)");
  cmd->add_option("inputs", req->inputs,
                  "Maps of any method, .bgk, .ot or .bt, or the shard folder of a distributed build (with --truth), "
                  "or scan files/folders (with --holdout)")
      ->required();
  cmd->add_option("--truth", req->truth, "Scene file (scene.yaml of `bgkmap simulate`) or truth .bt at the maps' resolution");
  cmd->add_option("--json", req->json, "Write the metrics here")->required();
  cmd->add_option("--truth-at", req->truth_at,
                  "With --truth SCENE.yaml of a dynamic scene: score against the scene as it is at this scan "
                  "(0-based; default its last scan)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--per-scan", req->per_scan,
                  "With --truth SCENE.yaml and the scene's scans as inputs: build them in order with --method and "
                  "score after every K scans (and the last) against the scene at that scan, one JSON row each "
                  "(all cells, static cells, removed-object and trail cells), 1 to 1000000")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--plot", req->plot, "Write ROC (false positive rate on a log axis) and precision-recall curves to this PNG")
      ->check(output_extension({".png"}, "eval --plot writes a PNG image"));
  cmd->add_option("--title", req->title, "Title of the --plot figure (default: what was scored)");
  cmd->add_option("--slice", req->slice, "Write a horizontal slice (probability, variance or evidence, truth) of the first map to this PNG")
      ->check(output_extension({".png"}, "eval --slice writes a PNG image"));
  cmd->add_option("--slice-z", req->slice_z, "Height of the slice (m); default as render's: the first map's layer with the most wall cells (occupied, occupied above and below, a seen unoccupied cell beside), else with the most occupied cells, else the middle of the evaluated box")
      ->check(finite_number("--slice-z", "height", "METRES"));
  cmd->add_option("--holdout", req->holdout,
                  "Build on the rest and score on this fraction (0..1) of the beams (--split beams) or of the scans (--split scans)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--seed", req->seed, "Seed of the held-out split")->capture_default_str();
  cmd->add_option("--split", req->split,
                  "With --holdout: hold out each scan's beams at random (beams), or whole scans in runs of "
                  "--run-length consecutive scans (scans: the Hilbert-maps protocol)")
      ->check(CLI::IsMember({"beams", "scans"}))
      ->capture_default_str();
  cmd->add_option("--run-length", req->run_length, "With --split scans: consecutive scans per held-out run")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--protocol", req->protocol,
                  "A paper's protocol on scans: bhm-table2 (Senanayake & Ramos 2018, Table 2): 10 % of each scan's beams "
                  "held out (--seed), the map scored after each update on the held-out beams so far; AUC and NLL as "
                  "mean +- 2 sigma over the updates")
      ->check(CLI::IsMember({"bhm-table2"}));
  cmd->add_option("--score-every", req->score_every, "With --protocol: score after every this many updates (and the last)")
      ->check(CLI::Range(uint64_t{1}, uint64_t{1000000}))
      ->capture_default_str();
  cmd->add_option("--spacing", req->spacing, "Free samples along held-out beams every this many metres (default: the resolution)")
      ->check(CLI::PositiveNumber & finite_number("--spacing", "spacing", "METRES"));
  cmd->add_option("--methods", req->methods,
                  "With --holdout: build and score each of these methods (comma-separated) on the same split, "
                  "overlaid in --plot; instead of --method")
      ->delimiter(',');
  add_progress_flags(*cmd, req->progress, "No progress bar or summary lines");
  const std::vector<CLI::Option*> eval_flags = cmd->get_options();
  req->options.add_to(*cmd);
  for (CLI::Option* option : cmd->get_options())
    if (std::find(eval_flags.begin(), eval_flags.end(), option) == eval_flags.end()) req->build_flags.push_back(option);
  req->method_option = cmd->get_option("--method");
  cmd->callback([req] { run_eval(*req); });
}

}  // namespace bgkmap::cli
