// bgkmap build: scans in, maps and a JSON report out (the library's BuildSession).
#include <cstdint>
#include <cstdio>
#include <memory>
#include <stdexcept>
#include <cstdlib>
#include <string>
#include <vector>

#include "bgkmap/build/build_session.hpp"
#include "bgkmap/dist/distributed_build.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/omp_wait_policy.hpp"
#include "cli/output_names.hpp"
#include "cli/ot_values_option.hpp"
#include "cli/progress.hpp"
#include "methods/bgkl/bgk_map_method.hpp"

namespace bgkmap::cli {

namespace {

// What the flags of `bgkmap build` write into.
struct BuildFlags {
  std::vector<std::string> inputs;
  std::vector<std::string> outputs;
  ResumeSettings resume;
  std::string report;
  ProgressFlags progress;
  bool skip_bad_inputs = false;
  std::string shards;
  std::string ot_values = "classified";  // --ot-values: what a .ot output holds
  BuildOptions options;
};

void add_resume_flags(CLI::App& cmd, ResumeSettings& resume) {
  cmd.add_option("--resume", resume.resume,
                 "Continue a native .bgk map: its parameters; the scans it already holds (same file contents) are "
                 "skipped (--method bgkl only). Under mpirun: the shard folder of an interrupted run, continued "
                 "from its last complete checkpoint (from the first scan if it wrote none)");
  cmd.add_option("--checkpoint-every", resume.every,
                 "Write the map atomically every N scans (to --checkpoint, else the first .bgk output), recording "
                 "the scans it holds: after a crash, the same command with --resume MAP.bgk finishes the same map. "
                 "Under mpirun: every rank's shard, in the shard folder")
      ->check(CLI::Validator(  // a uint64: "-1" would wrap to 2^64 - 1
          [](std::string& value) {
            return value.find_first_not_of("0123456789") == std::string::npos && !value.empty()
                       ? std::string()
                       : "'" + value + "' is not a count of scans (0 = none)";
          },
          "N"));
  cmd.add_option("--checkpoint", resume.checkpoint, "Where --checkpoint-every writes (a .bgk path)")
      ->check(output_extension({".bgk"}, "a checkpoint is a native .bgk map"));
}

// The flags (and --config) as the library's request.
BuildRequest request_from(const BuildFlags& flags) {
  const BuildOptions& options = flags.options;
  BuildRequest req;
  req.inputs = flags.inputs;
  req.outputs = flags.outputs;
  req.report = flags.report;
  req.ot_values = tree_values_from_string(flags.ot_values);
  req.source = options.resolve_source();
  req.params = options.resolve_params();
  req.backend = options.resolve_backend();
  req.method = options.method();
  options.check_method_flags_read_by({req.method});
  req.method_params = options.resolve_method_params();
  req.method_params_json = [](const MethodParams& params, const std::string& method) {
    return method_params_json(params, method);
  };
  req.resume = flags.resume;
  req.resume.params = [&options](const BuildParams& stored) { return options.resolve_params_for_resume(stored); };
  req.skip_bad_inputs = flags.skip_bad_inputs;
  if (!options.config_file().empty()) req.other_inputs.push_back({"--config", options.config_file()});
  req.note = [](const std::string& line) { std::fprintf(stderr, "bgkmap: %s\n", line.c_str()); };
  req.omp_wait_policy = omp_wait_policy();
  req.count_known_cells = !flags.report.empty();  // the summary line does without
  return req;
}

#ifdef BGKMAP_WITH_MPI
// Under mpirun: the distributed build (dist/distributed_build.hpp), BGK-L from the first scan.
void run_build_on_ranks(const BuildFlags& flags) {
  const BuildRequest req = request_from(flags);
  if (req.method != "bgkl")
    throw std::invalid_argument("a build under mpirun is BGK-L only, not --method " + req.method);
  if (!req.resume.checkpoint.empty())
    throw std::invalid_argument("under mpirun the checkpoints go to the shard folder (--shards), not --checkpoint");
  if (req.skip_bad_inputs) throw std::invalid_argument("--skip-bad-inputs is for a single-process build");
  if (req.method_params.number(forget_half_life_param().key) != 0)  // the ranks' shards keep no block times
    throw std::invalid_argument("--forget-half-life is for a single-process build");
  if (!req.params.preprocess.pose_sigma.is_zero() || !req.source.pose_covariance.empty())
    throw std::invalid_argument("a pose uncertainty (--pose-sigma, --pose-covariance) is for a single-process build");
  if (!req.source.poses.empty() || req.source.origin || req.source.kitti_frame != KittiFrame::kVelodyne)
    throw std::invalid_argument("--poses, --origin and --kitti-frame camera are for a single-process build");
  DistributedBuildRequest dist;
  static_cast<BuildTargets&>(dist) = req;
  dist.shards = flags.shards;
  dist.checkpoint_every = req.resume.every;
  dist.resume = req.resume.resume;
  dist.quiet = flags.progress.quiet;
  dist.report_fatal_signals = true;
  if (const char* kill = std::getenv("BGKMAP_KILL_RANK_AT")) dist.kill_rank_at = kill;  // the tests' fault injection
  run_distributed_build(dist);
}
#endif

// The one-line summary on stderr, and what to give for the points a build could not map.
void print_summary(const BuildReport& report) {
  const BuildCounts& c = report.counts;
  std::fprintf(stderr, "bgkmap: %llu scans, %llu hits, %llu beams, %zu blocks; insert %.3f s on %s (%s)\n",
               static_cast<unsigned long long>(c.scans), static_cast<unsigned long long>(c.preprocess.hits),
               static_cast<unsigned long long>(c.preprocess.beams), static_cast<size_t>(report.blocks_touched),
               report.timing.insert_s, report.backend.name.c_str(), report.backend.device.c_str());
  if (c.preprocess.dropped_beyond_reach > 0)
    std::fprintf(stderr, "bgkmap: %llu points farther than %.0f m from their sensor dropped: give --max-range to map them as free beams\n",
                 static_cast<unsigned long long>(c.preprocess.dropped_beyond_reach), kReachWithoutMaxRangeM);
  if (c.preprocess.no_returns_dropped > 0)
    std::fprintf(stderr, "bgkmap: %llu no-return readings dropped: give --max-range to use them as free beams\n",
                 static_cast<unsigned long long>(c.preprocess.no_returns_dropped));
}

void run_build(const BuildFlags& flags) {
#ifdef BGKMAP_WITH_MPI
  if (launched_by_mpirun()) return run_build_on_ranks(flags);
#endif
  if (!flags.shards.empty()) throw std::invalid_argument("--shards is for a build under mpirun");
  BuildRequest req = request_from(flags);
  ProgressBar progress(flags.progress);
  req.progress = progress.callback();
  const BuildReport report = BuildSession(std::move(req)).run();
  progress.finish();
  if (!flags.progress.quiet) print_summary(report);
}

// The methods that cannot write a .bgk, as -o's help lists them.
std::string methods_without_bgk() {
  std::vector<std::string> names;
  for (const MethodDescriptor* method : method_descriptors())
    if (!method->capabilities.writes_bgk) names.push_back(method->name);
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return out;
}

}  // namespace

void add_build_command(CLI::App& app) {
  auto req = std::make_shared<BuildFlags>();
  CLI::App* cmd = app.add_subcommand("build", "Build a map from scans (.pcd, OctoMap .graph or .dat log, CARMEN .log/.clf[.gz], .ply, .xyz, ROS 1 .bag, KITTI sequence folders, or folders of them) with BGK-L or a baseline (--method)");
  cmd->add_option("inputs", req->inputs, "Scan files or folders (folders: natural order, scan_2 before scan_10)")
      ->required();
  cmd->add_option("-o,--output", req->outputs, "Output map (repeat -o for several); format from the extension: .bgk (native; not --method " + methods_without_bgk() + "), .ot, .bt, or an export (not --method octomap; bgkmap export): .pgm (+ .yaml, ROS map_server; a 3-D map max-projected), .ply/.pcd (occupied cells; no variance field for gpom, wgpom, gpoctomap, bhm)")
      ->required()
      ->check(map_output_extension());
  add_resume_flags(*cmd, req->resume);
  cmd->add_option("--report", req->report, "Write a JSON report (parameters, counts, timings, back end, memory); a device or FIFO such as /dev/stdout is written through");
  add_ot_values_option(*cmd, req->ot_values);
  add_progress_flags(*cmd, req->progress, "No progress bar or summary");
  cmd->add_option("--shards", req->shards,
                  "Under mpirun: keep the ranks' shards and their manifest in this folder (also where checkpoints "
                  "go; default: the first output + \".shards\", removed at the end unless resuming (--resume) or an "
                  "output is not a .bgk file (merged from the shards); the ranks write -o .bgk outputs together");
  cmd->add_flag("--skip-bad-inputs", req->skip_bad_inputs,
                "A scan file that cannot be read is skipped (named on stderr, listed in the report) instead of "
                "stopping the build (a single-process build only)");
  req->options.add_to(*cmd);
  cmd->callback([req] { run_build(*req); });
}

}  // namespace bgkmap::cli
