// bgkmap build: scans in, maps and a JSON report out.
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/dist/distributed_build.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/occupancy_grid.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "cli/build_options.hpp"
#include "cli/commands.hpp"
#include "cli/omp_wait_policy.hpp"
#include "cli/output_names.hpp"
#include "cli/ot_values_option.hpp"
#include "cli/progress.hpp"
#include "cli/resumable_map.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap::cli {

namespace {

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux reports kilobytes
}

struct BuildRequest {
  std::vector<std::string> inputs;
  std::vector<std::string> outputs;
  ResumeOptions resume;
  std::string report;
  ProgressFlags progress;
  bool skip_bad_inputs = false;
  std::string shards;
  std::string ot_values = "classified";  // --ot-values: what a .ot output holds
  BuildOptions options;
};

// An input file --skip-bad-inputs passed over: its path and the one-line error.
struct SkippedInput {
  std::string path, error;
};

nlohmann::json make_report(const BuildRequest& req, MappingMethod& mapper, const ScanSource& source, double read_s,
                           double write_s, double total_s, const BackendOptions& backend_options) {
  const BuildCounts& c = mapper.counts();
  const InsertTiming& t = mapper.timing();
  nlohmann::json params = params_to_json(mapper.params());
  const BackendInfo backend = mapper.backend();
  params["method"] = mapper.name();
  const MethodParams method_params = req.options.resolve_method_params();
  params.update(method_params_json(method_params, mapper.name()));
  params["threads"] = backend_options.threads;
  params["backend"] = backend_options.backend;
  params["device"] = backend_options.device_filter;
  // Where the poses and their covariances came from, when not from the scans themselves.
  const ScanSourceOptions source_options = req.options.resolve_source();
  if (!source_options.poses.empty()) params["poses"] = source_options.poses.string();
  if (source_options.origin)
    params["origin"] = {source_options.origin->x, source_options.origin->y, source_options.origin->z};
  if (!source_options.pose_covariance.empty()) params["pose_covariance"] = source_options.pose_covariance.string();
  if (!source_options.topics.empty()) params["topics"] = source_options.topics;
  if (!source_options.tf_frame.empty()) params["tf_frame"] = source_options.tf_frame;
  nlohmann::json files = nlohmann::json::array();
  for (const auto& f : source.files()) files.push_back(f.string());
  return {
      {"params", params},
      {"inputs", files},
      {"outputs", req.outputs},
      {"ot_values", req.ot_values},
      {"counts",
       {{"scans", c.scans},
        {"points_read", c.preprocess.points_read},
        {"dropped_nonfinite", c.preprocess.dropped_nonfinite},
        {"dropped_out_of_key_range", c.preprocess.dropped_out_of_key_range},
        {"dropped_beyond_reach", c.preprocess.dropped_beyond_reach},
        {"removed_by_downsampling", c.preprocess.removed_by_downsampling},
        {"beyond_max_range", c.preprocess.beyond_max_range},
        {"no_returns", c.preprocess.no_returns},
        {"no_returns_dropped", c.preprocess.no_returns_dropped},
        {"skipped_messages", source.skipped_messages()},
        {"pose_sources", source.pose_sources()},
        {"hits", c.preprocess.hits},
        {"beams", c.preprocess.beams},
        {"beams_shorter_than_margin", c.preprocess.beams_shorter_than_margin},
        {"blocks_touched", mapper.blocks_touched()},
        {"block_visits", c.block_visits},
        {"cells_with_evidence", mapper.known_cells()},
        {"pairs_evaluated", c.integrate.pairs_evaluated},
        {"pairs_within_l", c.integrate.pairs_within_support},
        {"share_within_l", c.integrate.pairs_evaluated
                               ? double(c.integrate.pairs_within_support) / double(c.integrate.pairs_evaluated)
                               : 0.0}}},
      {"timing",
       {{"read_s", read_s},
        {"insert_s", t.insert_s},
        {"preprocess_s", t.preprocess_s},
        {"bucket_s", t.bucket_s},
        {"compute_s", t.compute_s},
        {"device_kernel_s", c.integrate.device_kernel_s},
        {"update_s", t.update_s},
        {"write_s", write_s},
        {"total_s", total_s},
        {"pairs_per_s", t.compute_s > 0 ? double(c.integrate.pairs_evaluated) / t.compute_s : 0.0},
        {"per_scan", mapper.per_scan_insert_s()}}},
      {"backend",
       {{"name", backend.name},
        {"device", backend.device},
        {"threads", backend.threads},
        {"note", backend.note},
        {"reason", backend.reason},
        {"omp_wait_policy", omp_wait_policy()}}},
      {"peak_rss_mb", peak_rss_mb()},
  };
}

// With at least this many host threads, one of them reads and prepares the next scan while the
// others map this one. It needs a core of its own: beside 16 mapping threads on 16 cores (even at
// nice 19) it held up their parallel loops and the whole campus took longer; on fewer cores the
// mapping threads cannot spare one.
constexpr int kReadAheadMinThreads = 8;

#ifdef BGKMAP_WITH_MPI
// Under mpirun: the distributed build (dist/distributed_build.hpp), BGK-L from the first scan.
void run_build_on_ranks(const BuildRequest& req) {
  if (req.options.method() != "bgkl")
    throw std::invalid_argument("a build under mpirun is BGK-L only, not --method " + req.options.method());
  if (!req.resume.checkpoint.empty())
    throw std::invalid_argument("under mpirun the checkpoints go to the shard folder (--shards), not --checkpoint");
  if (req.skip_bad_inputs) throw std::invalid_argument("--skip-bad-inputs is for a single-process build");
  DistributedBuildRequest dist;
  dist.inputs = req.inputs;
  dist.outputs = req.outputs;
  dist.shards = req.shards;
  dist.report = req.report;
  dist.checkpoint_every = req.resume.every;
  dist.resume = req.resume.resume;
  dist.quiet = req.progress.quiet;
  dist.ot_values = tree_values_from_string(req.ot_values);
  dist.params = req.options.resolve_params();
  const ScanSourceOptions source_options = req.options.resolve_source();
  if (!dist.params.preprocess.pose_sigma.is_zero() || !source_options.pose_covariance.empty())
    throw std::invalid_argument("a pose uncertainty (--pose-sigma, --pose-covariance) is for a single-process build");
  if (!source_options.poses.empty() || source_options.origin || source_options.kitti_frame != KittiFrame::kVelodyne)
    throw std::invalid_argument("--poses, --origin and --kitti-frame camera are for a single-process build");
  dist.backend = req.options.resolve_backend();
  dist.report_fatal_signals = true;
  run_distributed_build(dist);
}
#endif

std::vector<NamedPath> named_outputs(const BuildRequest& req) {
  std::vector<NamedPath> outputs;
  for (const std::string& out : req.outputs) outputs.push_back({"-o", out});
  if (!req.report.empty()) outputs.push_back({"--report", req.report});
  return outputs;
}

// What the build reads (not --resume's map: a resumed map is meant to be written again).
std::vector<NamedPath> named_inputs(const BuildRequest& req, const ScanSource& source, const ScanSourceOptions& options) {
  std::vector<NamedPath> inputs;
  for (const std::filesystem::path& file : source.files()) inputs.push_back({"input", file});
  if (!options.poses.empty()) inputs.push_back({"--poses", options.poses});
  if (!options.pose_covariance.empty()) inputs.push_back({"--pose-covariance", options.pose_covariance});
  if (!req.options.config_file().empty()) inputs.push_back({"--config", req.options.config_file()});
  return inputs;
}

void run_build(BuildRequest& req) {
#ifdef BGKMAP_WITH_MPI
  if (launched_by_mpirun()) return run_build_on_ranks(req);
#endif
  if (!req.shards.empty()) throw std::invalid_argument("--shards is for a build under mpirun");
  const Clock::time_point start = Clock::now();
  for (const std::string& out : req.outputs) check_map_output(out);
  if (!req.report.empty()) check_output_path(req.report);
  for (const std::string& out : req.outputs)  // one batch would keep only the later of the two
    if (!req.report.empty() && map_format_from_path(out) == MapFormat::kRosMap &&
        std::filesystem::path(req.report).lexically_normal() == ros_map_yaml_path(out).lexically_normal())
      throw std::invalid_argument("--report " + req.report + ": the map_server .yaml of -o " + out +
                                  " is written there; give the report another name");
  const ScanSourceOptions source_options = req.options.resolve_source();
  ScanSource source({req.inputs.begin(), req.inputs.end()}, source_options);
  check_outputs_apart(named_outputs(req), named_inputs(req, source, source_options));

  const BackendOptions asked = req.options.resolve_backend();
  BackendOptions backend_options = asked;
  const int host_threads = asked.threads > 0 ? asked.threads : static_cast<int>(std::thread::hardware_concurrency());
  const bool read_ahead = host_threads >= kReadAheadMinThreads;
  if (read_ahead) backend_options.threads = host_threads - 1;
  const std::string method = req.options.method();
  ResumableMap resumable(req.resume, req.outputs, method);
  std::unique_ptr<MappingMethod> mapper =
      method == "bgkl" ? resumable.make_method(req.options, backend_options, source)
                       : make_method(method, req.options.resolve_params(), req.options.resolve_method_params(),
                                     backend_options);
  if (!mapper->backend().note.empty()) std::fprintf(stderr, "bgkmap: warning: %s\n", mapper->backend().note.c_str());
  for (const std::string& out : req.outputs) mapper->check_output(out);
  check_one_pose_uncertainty(mapper->params().preprocess, source);  // on the resumed map's parameters too
  const KittiFrame kitti_frame = mapper->params().preprocess.kitti_frame;
  if (kitti_frame != source_options.kitti_frame)  // the source reads KITTI in the flags' frame
    throw std::invalid_argument(std::string("the resumed map's KITTI scans are in the ") + to_string(kitti_frame) +
                                " frame (kitti_frame): resume it with --kitti-frame " + to_string(kitti_frame));

  ProgressBar progress(req.progress);
  mapper->set_progress(progress.callback());
  // Reading and the voxel filter are serial: a seventh of a whole-campus build beside a GPU. With
  // read_ahead they run on their own thread, a scan ahead; a bad file's error comes out of get(),
  // after the scans before it are mapped (or, with --skip-bad-inputs, is noted and the next file
  // read).
  double read_s = 0;
  std::vector<SkippedInput> skipped;
  const PreprocessParams& preprocess = mapper->params().preprocess;
  struct ReadScan {
    PreparedScan prepared;
    size_t file;    // where it came from: ScanSource::last_file, last_scan
    uint64_t scan;
    ScanProgress read;  // the source's, taken on the thread that reads
  };
  auto read_next = [&]() -> std::optional<ReadScan> {
    Scan scan;
    for (;;) {
      const Clock::time_point t = Clock::now();
      bool more = false;
      try {
        more = source.next(scan);
      } catch (const InputError& e) {
        read_s += seconds_since(t);
        // A scan file (or a file of a KITTI folder) is passed over; a poses or covariance file that
        // does not fit concerns every scan.
        const bool about_every_scan = e.file() == source_options.poses || e.file() == source_options.pose_covariance;
        if (!req.skip_bad_inputs || about_every_scan) throw;
        skipped.push_back({e.file().string(), e.what()});
        std::fprintf(stderr, "bgkmap: skipping bad input %s\n", e.what());
        continue;
      }
      read_s += seconds_since(t);
      if (!more) return std::nullopt;
      return ReadScan{prepare_scan(scan, preprocess), source.last_file(), source.last_scan(), source.progress()};
    }
  };
  const std::launch policy = read_ahead ? std::launch::async : std::launch::deferred;
  std::future<std::optional<ReadScan>> next = std::async(policy, read_next);
  for (;;) {
    std::optional<ReadScan> read = next.get();
    if (!read) break;
    next = std::async(policy, read_next);
    mapper->check_pose_uncertainty(read->prepared);
    mapper->insert_prepared(std::move(read->prepared));
    resumable.inserted(source, read->file, read->scan);
    progress.report(scan_progress("build", read->read));
  }
  progress.report(scan_progress("build", source.progress()));  // exact now that every input is read
  progress.finish();
  if (!skipped.empty() && mapper->counts().scans == 0 && resumable.already_held() == 0)
    throw std::runtime_error("no input could be read (" + std::to_string(skipped.size()) + " skipped as bad)");

  // Every output is written to its temporary first and all are renamed together at the end: a
  // failure never leaves a new .bgk beside an old .ot.
  OutputBatch outputs;
  const Clock::time_point write_start = Clock::now();
  mapper->finish();
  progress.finish();
  for (const std::string& out : req.outputs)
    if (!resumable.write(out)) mapper->write(out, tree_values_from_string(req.ot_values));
  const double write_s = seconds_since(write_start);

  if (!req.report.empty()) {
    nlohmann::json report = make_report(req, *mapper, source, read_s, write_s, seconds_since(start), asked);
    resumable.add_to_report(report);
    report["counts"]["inputs_skipped"] = skipped.size();
    report["skipped_inputs"] = nlohmann::json::array();
    for (const SkippedInput& s : skipped) report["skipped_inputs"].push_back({{"path", s.path}, {"error", s.error}});
    write_file_atomically(req.report, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
  }
  outputs.commit();
  if (!req.progress.quiet) {
    const BuildCounts& c = mapper->counts();
    std::fprintf(stderr, "bgkmap: %llu scans, %llu hits, %llu beams, %zu blocks; insert %.3f s on %s (%s)\n",
                 static_cast<unsigned long long>(c.scans), static_cast<unsigned long long>(c.preprocess.hits),
                 static_cast<unsigned long long>(c.preprocess.beams), static_cast<size_t>(mapper->blocks_touched()),
                 mapper->timing().insert_s,
                 mapper->backend().name.c_str(), mapper->backend().device.c_str());
    if (c.preprocess.dropped_beyond_reach > 0)
      std::fprintf(stderr, "bgkmap: %llu points farther than %.0f m from their sensor dropped: give --max-range to map them as free beams\n",
                   static_cast<unsigned long long>(c.preprocess.dropped_beyond_reach), kReachWithoutMaxRangeM);
    if (c.preprocess.no_returns_dropped > 0)
      std::fprintf(stderr, "bgkmap: %llu no-return readings dropped: give --max-range to use them as free beams\n",
                   static_cast<unsigned long long>(c.preprocess.no_returns_dropped));
  }
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
  auto req = std::make_shared<BuildRequest>();
  CLI::App* cmd = app.add_subcommand("build", "Build a map from scans (.pcd, OctoMap .graph or .dat log, CARMEN .log/.clf[.gz], .ply, .xyz, ROS 1 .bag, KITTI sequence folders, or folders of them) with BGK-L or a baseline (--method)");
  cmd->add_option("inputs", req->inputs, "Scan files or folders (folders: natural order, scan_2 before scan_10)")
      ->required();
  cmd->add_option("-o,--output", req->outputs, "Output map (repeat -o for several); format from the extension: .bgk (native; not --method " + methods_without_bgk() + "), .ot, .bt, or an export (not --method octomap; bgkmap export): .pgm (+ .yaml, ROS map_server; a 3-D map max-projected), .ply/.pcd (occupied cells; no variance field for gpom, wgpom, gpoctomap, bhm)")
      ->required()
      ->check(map_output_extension());
  req->resume.add_to(*cmd);
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
