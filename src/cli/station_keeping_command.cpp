// bgkmap station-keeping: the experiment of T-RO 2019 §V-D. One scan is inserted again and again
// (as a robot standing still sees it) and a few named cells are read after 1, 15, 30, 60
// insertions: a method that treats repeated data as new evidence drifts there, BGK-L's mean holds
// while its variance shrinks. Every method is recursive, so the insertions are incremental.
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "bgkmap/core/params_io.hpp"
#include "bgkmap/eval/plot.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/methods/method.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/output_names.hpp"
#include "cli/progress.hpp"

namespace bgkmap::cli {

namespace {

struct NamedCell {
  std::string name;
  double x = 0, y = 0, z = 0;
};

struct StationKeepingRequest {
  std::string scan_file;
  std::vector<std::string> cell_specs;
  std::vector<int> repeats = {1, 15, 30, 60};
  std::vector<std::string> methods = method_names();
  std::string json_file;
  std::string plot_file;
  ProgressFlags progress;
  BuildOptions options;
};

// "NAME:X,Y,Z", NAME of letters, digits, '_' or '-'; throws std::invalid_argument saying so.
NamedCell parse_cell(const std::string& spec) {
  const auto refuse = [&](const std::string& why) {
    return std::invalid_argument("--cell '" + spec + "': " + why + " (expected NAME:X,Y,Z, e.g. wall:4.05,1.25,0.55)");
  };
  const size_t colon = spec.find(':');
  if (colon == std::string::npos) throw refuse("no ':' between the name and the coordinates");
  NamedCell cell;
  cell.name = spec.substr(0, colon);
  if (cell.name.empty()) throw refuse("empty name");
  for (char c : cell.name)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '-'))
      throw refuse("the name may hold letters, digits, '_' and '-' only");
  double* const coords[3] = {&cell.x, &cell.y, &cell.z};
  const char* p = spec.c_str() + colon + 1;
  for (int i = 0; i < 3; ++i) {
    char* end = nullptr;
    *coords[i] = std::strtod(p, &end);
    if (end == p || !std::isfinite(*coords[i])) throw refuse("coordinate " + std::to_string(i + 1) + " is not a number");
    p = end;
    if (i < 2) {
      if (*p != ',') throw refuse("expected three coordinates separated by ','");
      ++p;
    }
  }
  if (*p != '\0') throw refuse("unexpected text after the third coordinate");
  if (!within_key_range(cell.x, cell.y, cell.z)) throw refuse("beyond the map's key range (|x|, |y|, |z| at most 1e6 m)");
  return cell;
}

std::vector<NamedCell> parse_cells(const std::vector<std::string>& specs) {
  std::vector<NamedCell> cells;
  std::set<std::string> names;
  for (const std::string& spec : specs) {
    cells.push_back(parse_cell(spec));
    if (!names.insert(cells.back().name).second)
      throw std::invalid_argument("--cell: the name '" + cells.back().name + "' is given twice");
  }
  return cells;
}

void check_repeats(const std::vector<int>& repeats) {
  if (repeats.empty()) throw std::invalid_argument("--repeats: give at least one count");
  for (size_t i = 0; i < repeats.size(); ++i)
    if (repeats[i] < 1 || (i > 0 && repeats[i] <= repeats[i - 1]))
      throw std::invalid_argument("--repeats: counts must be >= 1 and increasing (e.g. 1,15,30,60)");
}

// The one scan SCAN holds (its pose and covariance from --poses, --origin, --pose-covariance as
// build takes them); a file or folder holding more is refused (the experiment repeats one).
Scan read_single_scan(const std::string& path, const ScanSourceOptions& options, const PreprocessParams& params) {
  ScanSource source({path}, options);
  check_one_pose_uncertainty(params, source);
  Scan scan, extra;
  if (!source.next(scan)) throw InputError(path, "holds no scan");
  if (source.next(extra))
    throw InputError(path, "holds more than one scan; station keeping repeats one (give a single scan file)");
  return scan;
}

// What the method's variance is the variance of, from one of its estimates.
const char* variance_kind(const std::string& method, const CellEstimate& e) {
  if (e.beta) return "beta_posterior";
  if (e.gp_mean && method == "wgpom") return "wgp_local_label";
  if (e.gp_mean) return method == "gpom" ? "gp_local_latent" : "gp_bcm_latent";
  if (e.logit_mean) return "bhm_logit";
  return "none";
}

nlohmann::json estimate_json(int insertions, const std::optional<CellEstimate>& e) {
  nlohmann::json j = {{"insertions", insertions}, {"known", e.has_value()}};
  j["mean"] = e ? nlohmann::json(e->occupancy) : nlohmann::json();
  j["variance"] = e && e->variance ? nlohmann::json(*e->variance) : nlohmann::json();
  if (e && e->beta) {
    j["alpha"] = e->beta->alpha;
    j["beta"] = e->beta->beta;
  }
  if (e && e->gp_mean) j["gp_mean"] = *e->gp_mean;
  if (e && e->logit_mean) j["logit_mean"] = *e->logit_mean;
  return j;
}

struct MethodRun {
  std::string method;
  std::string variance_of = "unknown";  // no cell known: nothing to tell
  // estimates[cell][k]: after repeats[k] insertions
  std::vector<std::vector<std::optional<CellEstimate>>> estimates;
};

MethodRun run_method(const std::string& name, const Scan& scan, const std::vector<NamedCell>& cells,
                     const std::vector<int>& repeats, const BuildParams& params, const MethodParams& method_params,
                     const BackendOptions& backend, ProgressBar& progress, uint64_t& inserted_total,
                     uint64_t insertions) {
  std::unique_ptr<MappingMethod> method = make_method(name, params, method_params, backend);
  if (!method->backend().note.empty())
    std::fprintf(stderr, "bgkmap: warning: %s: %s\n", name.c_str(), method->backend().note.c_str());
  MethodRun run;
  run.method = name;
  run.estimates.resize(cells.size());
  int inserted = 0;
  for (const int target : repeats) {
    for (; inserted < target; ++inserted) {
      method->insert(scan);
      progress.report({"station-keeping", "insertions", ++inserted_total, insertions, false});
    }
    method->finish();
    for (size_t c = 0; c < cells.size(); ++c) {
      const std::optional<CellEstimate> e = method->estimate(cells[c].x, cells[c].y, method->query_z(cells[c].z));
      if (e) run.variance_of = variance_kind(name, *e);
      run.estimates[c].push_back(e);
    }
  }
  return run;
}

std::string legend_label(const MethodRun& run) {
  if (run.variance_of == "none") return run.method + " (no variance)";
  if (run.variance_of == "gp_bcm_latent" || run.variance_of == "gp_local_latent")
    return run.method + " (variance of the latent GP value)";
  if (run.variance_of == "bhm_logit") return run.method + " (variance of the logit)";
  if (run.variance_of == "wgp_local_label") return run.method + " (variance of the unwarped label)";
  return run.method;
}

void write_plot(const std::string& file, const StationKeepingRequest& req, const std::vector<NamedCell>& cells,
                const std::vector<MethodRun>& runs) {
  std::vector<eval::LinePanel> panels;
  const std::vector<double> xs(req.repeats.begin(), req.repeats.end());
  for (size_t c = 0; c < cells.size(); ++c) {
    eval::LinePanel mean;
    mean.title = cells[c].name + ": mean";
    mean.xlabel = "insertions of the scan";
    mean.ylabel = "P(occupied)";
    mean.y_min = 0;
    mean.y_max = 1;
    eval::LinePanel variance;
    variance.title = cells[c].name + ": variance";
    variance.xlabel = "insertions of the scan";
    variance.ylabel = "variance (log)";
    variance.log_y = true;
    for (const MethodRun& run : runs) {
      eval::LineSeries m{legend_label(run), xs, {}}, v{legend_label(run), xs, {}};
      for (const std::optional<CellEstimate>& e : run.estimates[c]) {
        m.y.push_back(e ? e->occupancy : std::nan(""));
        v.y.push_back(e && e->variance ? *e->variance : std::nan(""));
      }
      mean.series.push_back(m);
      if (run.variance_of != "none") variance.series.push_back(v);
    }
    panels.push_back(mean);
    panels.push_back(variance);
  }
  eval::write_line_panels_png(file, panels, 2,
                              "Station keeping: " + std::filesystem::path(req.scan_file).filename().string() +
                                  " inserted repeatedly");
}

void print_table(const std::vector<NamedCell>& cells, const std::vector<int>& repeats, const Grid& grid,
                 const std::vector<MethodRun>& runs) {
  for (size_t c = 0; c < cells.size(); ++c) {
    const Vec3d centre = grid.cell_center_d(grid.cell_of(cells[c].x, cells[c].y, cells[c].z));
    std::printf("%s (cell centre %.3f %.3f %.3f): mean (variance) after N insertions\n", cells[c].name.c_str(),
                centre.x, centre.y, centre.z);
    std::printf("  %-10s", "method");
    for (int n : repeats) std::printf(" %22s", ("N=" + std::to_string(n)).c_str());
    std::printf("\n");
    for (const MethodRun& run : runs) {
      std::printf("  %-10s", run.method.c_str());
      for (const std::optional<CellEstimate>& e : run.estimates[c]) {
        char cell_text[64];
        if (!e) std::snprintf(cell_text, sizeof cell_text, "unknown");
        else if (!e->variance) std::snprintf(cell_text, sizeof cell_text, "%.4f (-)", e->occupancy);
        else std::snprintf(cell_text, sizeof cell_text, "%.4f (%.3g)", e->occupancy, *e->variance);
        std::printf(" %22s", cell_text);
      }
      std::printf("\n");
    }
  }
}

void run_station_keeping(StationKeepingRequest& req) {
  const std::vector<NamedCell> cells = parse_cells(req.cell_specs);
  check_repeats(req.repeats);
  check_output_path(req.json_file);
  if (!req.plot_file.empty()) check_output_path(req.plot_file);
  const BuildParams params = req.options.resolve_params();
  req.options.check_method_flags_read_by(req.methods);
  const MethodParams method_params = req.options.resolve_method_params();
  const BackendOptions backend = req.options.resolve_backend();
  const Scan scan = read_single_scan(req.scan_file, req.options.resolve_source(), params.preprocess);

  ProgressBar progress(req.progress);
  const uint64_t insertions = uint64_t(req.repeats.back()) * req.methods.size();
  uint64_t inserted_total = 0;
  std::vector<MethodRun> runs;
  for (const std::string& name : req.methods)
    runs.push_back(
        run_method(name, scan, cells, req.repeats, params, method_params, backend, progress, inserted_total, insertions));
  progress.finish();

  const Grid grid(params.grid);
  nlohmann::json json_cells = nlohmann::json::array();
  for (const NamedCell& cell : cells) {
    const Vec3d centre = grid.cell_center_d(grid.cell_of(cell.x, cell.y, cell.z));
    json_cells.push_back({{"name", cell.name}, {"query", {cell.x, cell.y, cell.z}}, {"centre", {centre.x, centre.y, centre.z}}});
  }
  nlohmann::json json_methods = nlohmann::json::array();
  for (const MethodRun& run : runs) {
    nlohmann::json per_cell = nlohmann::json::object();
    for (size_t c = 0; c < cells.size(); ++c) {
      nlohmann::json series = nlohmann::json::array();
      for (size_t k = 0; k < req.repeats.size(); ++k) series.push_back(estimate_json(req.repeats[k], run.estimates[c][k]));
      per_cell[cells[c].name] = series;
    }
    json_methods.push_back({{"method", run.method}, {"variance_of", run.variance_of}, {"cells", per_cell}});
  }
  nlohmann::json json_params = params_to_json(params);
  json_params.update(method_params_json(method_params));
  const nlohmann::json report = {{"scan", req.scan_file}, {"repeats", req.repeats}, {"params", json_params},
                                 {"cells", json_cells}, {"methods", json_methods}};
  OutputBatch outputs;  // the JSON and the plot renamed into place together
  write_file_atomically(req.json_file, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
  if (!req.plot_file.empty()) write_plot(req.plot_file, req, cells, runs);
  outputs.commit();
  if (!req.progress.quiet) print_table(cells, req.repeats, grid, runs);
}

}  // namespace

void add_station_keeping_command(CLI::App& app) {
  auto req = std::make_shared<StationKeepingRequest>();
  CLI::App* cmd = app.add_subcommand(
      "station-keeping",
      "Insert one scan repeatedly (default 1, 15, 30, 60 times) and report each method's mean and variance at named "
      "cells (T-RO 2019 §V-D)");
  cmd->add_option("scan", req->scan_file, "One scan (.pcd, or a .graph / folder holding a single scan)")->required();
  cmd->add_option("--cell", req->cell_specs, "NAME:X,Y,Z: a cell to read (the one holding that point); repeatable")
      ->required();
  cmd->add_option("--repeats", req->repeats, "Insertion counts to read the cells at, increasing")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--methods", req->methods,
                  "Methods to compare: bgkl, bgk, counting, octomap, gpoctomap, gpom, wgpom, bhm (see build --help); "
                  "variance is the Beta posterior's (bgkl, bgk, counting), the BCM-fused GP prediction's (gpoctomap), "
                  "the local GP model's latent variance (gpom), the unwarped label's (wgpom), the logit's (bhm), none "
                  "for octomap")
      ->delimiter(',')
      ->check(CLI::IsMember(method_names()))
      ->capture_default_str();
  cmd->add_option("--json", req->json_file,
                  "Write the estimates: per method and cell, mean, variance (null where the method has none), "
                  "alpha/beta or the GP's latent mean, after each count")
      ->required();
  cmd->add_option("--plot", req->plot_file, "PNG: mean and variance (log) against insertions, a row per cell")
      ->check(output_extension({".png"}, "station-keeping --plot writes a PNG image"));
  add_progress_flags(*cmd, req->progress, "No progress bar or table");
  req->options.add_to(*cmd, MethodChoice::kByCommand);
  cmd->callback([req] { run_station_keeping(*req); });
}

}  // namespace bgkmap::cli
