// bgkmap simulate: a built-in preset or a scene file in, scans + poses + truth out (docs/SIMULATOR.md).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>

#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/sim/presets.hpp"
#include "bgkmap/sim/simulate.hpp"
#include "cli/commands.hpp"
#include "cli/progress.hpp"

namespace bgkmap::cli {

namespace {

struct SimulateRequest {
  std::string source;  // preset name or scene file
  std::string output_dir;
  std::optional<uint64_t> seed;
  std::optional<double> noise, dropout, truth_resolution;
  std::optional<int> scans;
  std::string sensor;
  std::string drift;  // --drift XY,YAW[,Z,ROLLPITCH]
  bool overwrite = false;
  ProgressFlags progress;
};

std::string preset_list() {
  std::string list;
  for (const auto& n : sim::preset_names()) list += (list.empty() ? "" : ", ") + n;
  return list;
}

sim::SimulationSpec load_source(const std::string& source) {
  if (sim::is_preset(source)) return sim::make_preset(source);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(source, ec))
    throw InputError(source, "neither a preset (" + preset_list() + ") nor a scene file");
  return sim::load_spec(source);
}

sim::SensorModel load_sensor_option(const std::string& sensor) {
  for (const auto& n : sim::sensor_preset_names())
    if (n == sensor) return sim::sensor_preset(sensor);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(sensor, ec)) {
    std::string list;
    for (const auto& n : sim::sensor_preset_names()) list += (list.empty() ? "" : ", ") + n;
    throw InputError(sensor, "--sensor is neither a sensor preset (" + list + ") nor a sensor .yaml file");
  }
  return sim::load_sensor(sensor);
}

// Command-line settings override the preset's or the scene file's.
void apply_overrides(const SimulateRequest& req, sim::SimulationSpec& spec) {
  if (!req.sensor.empty()) spec.sensor = load_sensor_option(req.sensor);
  if (req.seed) spec.seed = *req.seed;
  if (req.noise) spec.sensor.range_noise_sigma_m = *req.noise;
  if (req.dropout) spec.sensor.dropout = *req.dropout;
  if (req.scans) spec.trajectory.scans = *req.scans;
  if (req.truth_resolution) spec.truth_resolution_m = *req.truth_resolution;
  try {
    spec.validate();
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("simulate: ") + e.what());
  }
}

void run(const SimulateRequest& req) {
  sim::SimulationSpec spec = load_source(req.source);
  apply_overrides(req, spec);
  const std::filesystem::path out = req.output_dir;
  check_output_folder(out);

  ProgressBar progress(req.progress);
  sim::SimulateOptions options;
  options.output_dir = out;
  options.overwrite = req.overwrite;
  if (!req.drift.empty()) {
    try {
      options.drift = parse_pose_sigma(req.drift, "--drift");
    } catch (const std::invalid_argument& e) {
      throw std::runtime_error(std::string("simulate: ") + e.what());
    }
  }
  options.on_scan = [&](size_t done, size_t total) {
    progress.report({"simulate " + spec.name, "scans", done, total, false});
  };
  if (!req.progress.quiet) {
    std::fprintf(stderr, "simulating '%s': %zu primitives, %s sensor (%zu beams), %d scans -> %s\n", spec.name.c_str(),
                 spec.scene.primitives.size(), spec.sensor.name.c_str(), spec.sensor.beam_count(),
                 spec.trajectory.scans, out.string().c_str());
  }
  const sim::SimulateReport report = sim::simulate(spec, options);
  progress.finish();
  if (req.progress.quiet) return;

  const sim::ScanCounts& c = report.counts;
  std::printf("scans:  %zu in %.1f s, %.1f MB in %s\n", report.scans, report.scan_seconds, report.scan_bytes / 1e6,
              (out / "scans").string().c_str());
  std::printf("beams:  %llu: %llu returns, %llu no-returns (stored at %g m), %llu dropped (NaN)\n",
              static_cast<unsigned long long>(c.beams), static_cast<unsigned long long>(c.returns),
              static_cast<unsigned long long>(c.no_returns), sim::kNoReturnRangeFactor * spec.sensor.max_range_m,
              static_cast<unsigned long long>(c.dropped));
  if (report.truth) {
    std::printf("truth:  %s at %g m: %llu occupied and %llu free cells, %.1f s\n", (out / "truth.bt").string().c_str(),
                spec.truth_resolution_m, static_cast<unsigned long long>(report.truth->occupied_cells),
                static_cast<unsigned long long>(report.truth->free_cells), report.truth_seconds);
  }
  std::printf("also:   %s, %s\n", (out / "poses.txt").string().c_str(), (out / "scene.yaml").string().c_str());
  const bool drift = !options.drift.is_zero();
  if (drift)
    std::printf("drift:  scans seen from the drifted poses in poses.txt (with their covariance); true poses in %s\n",
                (out / "poses_true.txt").string().c_str());
  std::printf("build:  bgkmap build %s %s%s%s -o map.bt\n", (out / "scans").string().c_str(),
              sim::recommended_build_flags(spec).c_str(), drift ? " --pose-covariance " : "",
              drift ? (out / "poses.txt").string().c_str() : "");
  std::printf("        (any --max-range up to the sensor's %g m turns no-returns into free beams; without one\n"
              "        they would be read as hits %g m away)\n",
              spec.sensor.max_range_m, sim::kNoReturnRangeFactor * spec.sensor.max_range_m);
}

}  // namespace

void add_simulate_command(CLI::App& app) {
  auto req = std::make_shared<SimulateRequest>();
  CLI::App* cmd = app.add_subcommand(
      "simulate", "Simulate range scans of a built-in scene (" + preset_list() + ") or a scene .yaml file");
  cmd->add_option("source", req->source, "Preset name (" + preset_list() + ") or scene .yaml file")->required();
  cmd->add_option("-o,--output", req->output_dir, "Output folder: scans/, poses.txt, scene.yaml, truth.bt")->required();
  cmd->add_option("--seed", req->seed, "Seed of range noise and dropout (the scene geometry never depends on it)");
  cmd->add_option("--noise", req->noise, "Range noise sigma in metres (default: the sensor's)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--dropout", req->dropout, "Probability that a return is lost (written as NaN)")
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_option("--scans", req->scans, "Number of scans (overrides the trajectory's)")->check(CLI::PositiveNumber);
  cmd->add_option("--truth-resolution", req->truth_resolution, "Cell size of truth.bt in metres; 0: no truth.bt")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--drift", req->drift,
                  "Odometry drift XY,YAW or XY,YAW,Z,ROLLPITCH: standard deviations (m, rad) of each scan's "
                  "increment of pose error (a random walk); scans are written as the drifted poses see them");
  cmd->add_option("--sensor", req->sensor, "Sensor preset (vlp16, planar, depth-camera) or a sensor .yaml file");
  cmd->add_flag("--overwrite", req->overwrite, "Replace the .pcd files of an earlier run in the output's scans/");
  add_progress_flags(*cmd, req->progress, "No progress bar or summary");
  cmd->callback([req] { run(*req); });
}

}  // namespace bgkmap::cli
