#include "bgkmap/build/build_session.hpp"

#include <sys/resource.h>

#include <filesystem>
#include <future>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/occupancy_grid.hpp"
#include "build/resumable_map.hpp"
#include "methods/bgkl/bgk_map_method.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

namespace {

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;  // Linux reports kilobytes
}

// With this many host threads one of them reads and prepares the next scan: fewer cannot spare a
// core for it (docs/DESIGN.md, "Data flow").
constexpr int kReadAheadMinThreads = 8;

std::vector<NamedPath> named_outputs(const BuildRequest& req) {
  std::vector<NamedPath> outputs;
  for (const std::string& out : req.outputs) outputs.push_back({"-o", out});
  if (!req.report.empty()) outputs.push_back({"--report", req.report});
  return outputs;
}

// What the build reads (not the resumed map: a resumed map is meant to be written again).
std::vector<NamedPath> named_inputs(const BuildRequest& req, const ScanSource& source) {
  std::vector<NamedPath> inputs;
  for (const std::filesystem::path& file : source.files()) inputs.push_back({"input", file});
  if (!req.source.poses.empty()) inputs.push_back({"--poses", req.source.poses});
  if (!req.source.pose_covariance.empty()) inputs.push_back({"--pose-covariance", req.source.pose_covariance});
  inputs.insert(inputs.end(), req.other_inputs.begin(), req.other_inputs.end());
  return inputs;
}

// The outputs' names and folders, before any scan is read.
void check_outputs(const BuildRequest& req) {
  for (const std::string& out : req.outputs) check_map_output(out);
  if (!req.report.empty()) check_output_path(req.report);
  for (const std::string& out : req.outputs)  // one batch would keep only the later of the two
    if (!req.report.empty() && map_format_from_path(out) == MapFormat::kRosMap &&
        std::filesystem::path(req.report).lexically_normal() == ros_map_yaml_path(out).lexically_normal())
      throw std::invalid_argument("--report " + req.report + ": the map_server .yaml of -o " + out +
                                  " is written there; give the report another name");
}

// The settings the method's own map must agree with, checked on a resumed map's parameters too.
void check_method(const BuildRequest& req, MappingMethod& method, const ScanSource& source) {
  for (const std::string& out : req.outputs) method.check_output(out);
  check_one_pose_uncertainty(method.params().preprocess, source);
  const KittiFrame kitti_frame = method.params().preprocess.kitti_frame;
  if (kitti_frame != req.source.kitti_frame)  // the source reads KITTI in the request's frame
    throw std::invalid_argument(std::string("the resumed map's KITTI scans are in the ") + to_string(kitti_frame) +
                                " frame (kitti_frame): resume it with --kitti-frame " + to_string(kitti_frame));
}

struct ReadScan {
  PreparedScan prepared;
  size_t file;  // where it came from: ScanSource::last_file, last_scan
  uint64_t scan;
  ScanProgress read;  // the source's, taken on the thread that reads
};

// Reads and prepares the scans one at a time, maybe on a thread of its own a scan ahead; a bad
// file's error comes out of next() after the scans before it (or, skipping bad inputs, is noted
// and the next file read).
class ScanFeed {
 public:
  ScanFeed(const BuildRequest& req, ScanSource& source, const PreprocessParams& preprocess, bool ahead)
      : req_(req), source_(source), preprocess_(preprocess),
        policy_(ahead ? std::launch::async : std::launch::deferred), next_(std::async(policy_, [this] { return read(); })) {}

  std::optional<ReadScan> next() {
    std::optional<ReadScan> scan = next_.get();
    if (scan) next_ = std::async(policy_, [this] { return read(); });
    return scan;
  }
  double read_s() const { return read_s_; }
  const std::vector<SkippedInput>& skipped() const { return skipped_; }

 private:
  std::optional<ReadScan> read() {
    Scan scan;
    for (;;) {
      const Clock::time_point t = Clock::now();
      bool more = false;
      try {
        more = source_.next(scan);
      } catch (const InputError& e) {
        read_s_ += seconds_since(t);
        // A scan file (or a file of a KITTI folder) is passed over; a poses or covariance file that
        // does not fit concerns every scan.
        const bool about_every_scan = e.file() == req_.source.poses || e.file() == req_.source.pose_covariance;
        if (!req_.skip_bad_inputs || about_every_scan) throw;
        skipped_.push_back({e.file().string(), e.what()});
        if (req_.note) req_.note(std::string("skipping bad input ") + e.what());
        continue;
      }
      read_s_ += seconds_since(t);
      if (!more) return std::nullopt;
      return ReadScan{prepare_scan(scan, preprocess_), source_.last_file(), source_.last_scan(), source_.progress()};
    }
  }

  const BuildRequest& req_;
  ScanSource& source_;
  const PreprocessParams& preprocess_;
  double read_s_ = 0;
  std::vector<SkippedInput> skipped_;
  std::launch policy_;
  std::future<std::optional<ReadScan>> next_;
};

Progress scans_read(const ScanProgress& scans) { return {"build", "scans", scans.done, scans.total, scans.estimated}; }

// What the build did, for the report (its write and total times aside).
BuildReport report_of(const BuildRequest& req, MappingMethod& method, const ScanSource& source, const ScanFeed& feed,
                      const ResumableMap& resumable) {
  BuildReport report;
  report.method = method.name();
  report.params = method.params();
  if (req.method_params_json) report.method_params = req.method_params_json(req.method_params, report.method);
  report.backend_asked = req.backend;
  report.source = req.source;
  for (const auto& f : source.files()) report.inputs.push_back(f.string());
  report.outputs = req.outputs;
  report.ot_values = req.ot_values;
  report.counts = method.counts();
  report.blocks_touched = method.blocks_touched();
  if (req.count_known_cells) report.known_cells = method.known_cells();
  report.skipped_messages = source.skipped_messages();
  report.pose_sources = source.pose_sources();
  report.skipped = feed.skipped();
  resumable.add_to(report);
  report.timing = method.timing();
  report.read_s = feed.read_s();
  report.peak_rss_mb = peak_rss_mb();
  report.backend = method.backend();
  report.omp_wait_policy = req.omp_wait_policy;
  return report;
}

}  // namespace

void check_one_pose_uncertainty(const PreprocessParams& params, const ScanSource& source) {
  if (!params.pose_sigma.is_zero() && source.carries_pose_covariances())
    throw std::invalid_argument("give a constant pose uncertainty (--pose-sigma, or the resumed map's pose_sigma) or "
                                "covariances per scan (--pose-covariance, --poses with covariances), not both");
}

BuildReport BuildSession::run() {
  const BuildRequest& req = request_;
  const Clock::time_point start = Clock::now();
  const auto note = [&req](const std::string& line) {
    if (req.note) req.note(line);
  };
  check_outputs(req);
  ScanSource source({req.inputs.begin(), req.inputs.end()}, req.source);
  check_outputs_apart(named_outputs(req), named_inputs(req, source));

  BackendOptions backend = req.backend;
  const int host_threads = backend.threads > 0 ? backend.threads : static_cast<int>(std::thread::hardware_concurrency());
  const bool read_ahead = host_threads >= kReadAheadMinThreads;
  if (read_ahead) backend.threads = host_threads - 1;
  ResumableMap resumable(req.resume, req.outputs, req.method);
  const double forget_half_life = req.method_params.number(forget_half_life_param().key);
  std::unique_ptr<MappingMethod> method = req.method == "bgkl"
                                              ? resumable.make_method(req.params, forget_half_life, backend, source, note)
                                              : make_method(req.method, req.params, req.method_params, backend);
  if (!method->backend().note.empty()) note("warning: " + method->backend().note);
  check_method(req, *method, source);

  method->set_progress(req.progress);
  const auto progress = [&req](const Progress& p) {
    if (req.progress) req.progress(p);
  };
  ScanFeed feed(req, source, method->params().preprocess, read_ahead);
  while (std::optional<ReadScan> read = feed.next()) {
    method->check_pose_uncertainty(read->prepared);
    method->insert_prepared(std::move(read->prepared));
    resumable.inserted(source, read->file, read->scan);
    progress(scans_read(read->read));
  }
  progress(scans_read(source.progress()));  // exact now that every input is read
  if (!feed.skipped().empty() && method->counts().scans == 0 && resumable.already_held() == 0)
    throw std::runtime_error("no input could be read (" + std::to_string(feed.skipped().size()) + " skipped as bad)");

  // Every output goes to its temporary first and all are renamed together at the end: a failure
  // never leaves a new .bgk beside an old .ot.
  OutputBatch outputs;
  const Clock::time_point write_start = Clock::now();
  method->finish();
  for (const std::string& out : req.outputs)
    if (!resumable.write(out)) method->write(out, req.ot_values);

  const double write_s = seconds_since(write_start);
  BuildReport report = report_of(req, *method, source, feed, resumable);
  report.write_s = write_s;
  report.total_s = seconds_since(start);
  if (!req.report.empty())
    write_file_atomically(req.report, [&](std::ostream& out) { out << report_json(report).dump(2) << '\n'; });
  outputs.commit();
  return report;
}

}  // namespace bgkmap
