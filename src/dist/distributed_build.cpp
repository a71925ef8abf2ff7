// The MPI side of a distributed build. Every MPI call of the project is in this file.
#include "bgkmap/dist/distributed_build.hpp"

#include <mpi.h>
#include <sys/resource.h>
#include <fcntl.h>
#include <unistd.h>

#include <csignal>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <thread>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/dist/partition.hpp"
#include "bgkmap/dist/routing.hpp"
#include "bgkmap/dist/shards.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/held_inputs.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap {

bool launched_by_mpirun() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE"})
    if (std::getenv(name) != nullptr) return true;
  return false;
}

namespace {

// Scans in global order (files in order, a .pcd one scan, a .graph or log one per node or
// message), the share of rank r being scans r, r+K, ...: a .pcd outside the share is never
// opened; multi-scan files are read through by every rank (their scans cannot be found otherwise).
class ShareReader {
 public:
  // Scans before `first` (held by a checkpoint) belong to no share; from it on, rank r's are
  // first + r, first + r + K, ...
  ShareReader(std::vector<std::filesystem::path> files, int ranks, int rank, uint64_t first = 0)
      : files_(std::move(files)), ranks_(ranks), rank_(rank), first_(first), scans_in_file_(files_.size(), 0) {}

  // The next scan of this rank's share; `global` is its global number. A file that cannot be
  // read throws std::runtime_error "scan G: FILE: what is wrong".
  bool next(Scan& scan, uint64_t& global) {
    try {
      return read_next(scan, global);
    } catch (const InputError& e) {
      throw std::runtime_error("scan " + std::to_string(counter_) + ": " + e.what());
    }
  }
  // After the last next(): scans in each file and in all.
  const std::vector<uint64_t>& scans_in_file() const { return scans_in_file_; }
  uint64_t scans() const { return counter_; }

 private:
  bool owns(uint64_t g) const {
    return g >= first_ && (g - first_) % static_cast<uint64_t>(ranks_) == static_cast<uint64_t>(rank_);
  }

  // counter_ is the number of the scan being read until it is returned.
  bool read_next(Scan& scan, uint64_t& global) {
    for (;;) {
      if (multi_) {
        Scan s;
        if (multi_->next(s)) {
          const uint64_t g = counter_++;
          ++scans_in_file_[file_];
          if (owns(g)) {
            scan = std::move(s);
            global = g;
            return true;
          }
          continue;
        }
        multi_.reset();
        ++file_;
        continue;
      }
      if (file_ >= files_.size()) return false;
      if (scan_file_type(files_[file_]) == ScanFileType::kPcd) {
        const size_t f = file_++;
        scans_in_file_[f] = 1;
        if (!owns(counter_)) {
          ++counter_;
          continue;
        }
        ScanSource one({files_[f]});
        if (!one.next(scan)) scan = Scan{};
        global = counter_++;
        return true;
      }
      multi_.emplace(std::vector<std::filesystem::path>{files_[file_]});
    }
  }

  std::vector<std::filesystem::path> files_;
  int ranks_, rank_;
  uint64_t first_;
  size_t file_ = 0;
  uint64_t counter_ = 0;
  std::optional<ScanSource> multi_;
  std::vector<uint64_t> scans_in_file_;
};

[[noreturn]] void abort_job(int rank, const std::string& what) {
  std::fprintf(stderr, "bgkmap: rank %d: %s\n", rank, what.c_str());
  std::fflush(stderr);
  MPI_Abort(MPI_COMM_WORLD, 1);
  std::exit(1);
}

double peak_rss_mb() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return usage.ru_maxrss / 1024.0;
}

// One scan's observations for one rank, as bytes: u64 global scan, f32 origin[3], u32 hits,
// u32 free ends, then the points (f32 x, y, z each).
void pack(std::vector<char>& out, uint64_t scan, const ScanObservations& obs, const std::vector<uint32_t>& hits,
          const std::vector<uint32_t>& ends) {
  const size_t start = out.size();
  const uint32_t nh = static_cast<uint32_t>(hits.size()), nb = static_cast<uint32_t>(ends.size());
  out.resize(start + 8 + 12 + 8 + 12 * (size_t(nh) + nb));
  char* p = out.data() + start;
  std::memcpy(p, &scan, 8);
  std::memcpy(p + 8, &obs.origin, 12);
  std::memcpy(p + 20, &nh, 4);
  std::memcpy(p + 24, &nb, 4);
  p += 28;
  for (const uint32_t i : hits) std::memcpy(p, &obs.hits[i], 12), p += 12;
  for (const uint32_t i : ends) std::memcpy(p, &obs.free_ends[i], 12), p += 12;
}

const char* unpack(const char* p, uint64_t& scan, ScanObservations& obs) {
  uint32_t nh = 0, nb = 0;
  std::memcpy(&scan, p, 8);
  std::memcpy(&obs.origin, p + 8, 12);
  std::memcpy(&nh, p + 20, 4);
  std::memcpy(&nb, p + 24, 4);
  p += 28;
  obs.hits.resize(nh);
  obs.free_ends.resize(nb);
  if (nh) std::memcpy(obs.hits.data(), p, 12 * size_t(nh));
  p += 12 * size_t(nh);
  if (nb) std::memcpy(obs.free_ends.data(), p, 12 * size_t(nb));
  return p + 12 * size_t(nb);
}

static_assert(sizeof(Vec3f) == 12, "points travel as three packed floats");

// Per-rank figures gathered into rank 0's report, in this order.
enum Figure {
  kScansRead, kReadS, kRouteS, kExchangeS, kInsertS, kBucketS, kComputeS, kWriteShardS, kBytesSent, kBytesReceived,
  kObservationsSent, kObservationsRead, kBlocks, kPeakRssMb, kEstimatedCost, kFootprintS, kWaitS, kFigureCount
};
const char* const kFigureNames[kFigureCount] = {
    "scans_read", "read_s", "route_s", "exchange_s", "insert_s", "bucket_s", "compute_s", "write_shard_s",
    "bytes_sent", "bytes_received", "observations_sent", "observations_read", "blocks", "peak_rss_mb",
    "estimated_cost", "footprint_s", "wait_s"};

// The partition's cost estimate uses every kFootprintStride-th scan of each rank's share: the
// footprints of neighbouring scans overlap, and the estimate costs more than reading the scan.
constexpr uint64_t kFootprintStride = 4;

// What each rank is doing, for the lines printed when the job ends abnormally. Every rank keeps
// one fixed-width line of its own in the shard folder's progress file, rewritten in place at each
// step (pwrite: a rank killed outright leaves its last line behind). A rank ended by a signal it
// can catch prints its own line; rank 0, ended because another rank died (mpirun then sends
// SIGTERM), prints every rank's, so the dead rank's scan is named beside mpirun's line naming the
// rank; a resumed run prints the lines the interrupted one left.
constexpr size_t kProgressLine = 128;
char g_doing[kProgressLine] = "starting";
int g_rank = 0, g_ranks = 1, g_progress_fd = -1;
std::vector<char> g_progress_table;  // sized before the handlers can run: a handler cannot allocate

std::string progress_line(int rank, const char* doing) {
  std::string line = "rank " + std::to_string(rank) + ": " + doing;
  line.resize(kProgressLine - 1, ' ');
  return line + '\n';
}

void record_doing() {
  if (g_progress_fd < 0) return;
  const std::string line = progress_line(g_rank, g_doing);
  (void)!pwrite(g_progress_fd, line.data(), line.size(), static_cast<off_t>(g_rank) * off_t(kProgressLine));
}

void set_doing(const std::string& what) {
  std::snprintf(g_doing, sizeof g_doing, "%s", what.c_str());
  record_doing();
}

// Rank 0 opens (creates) the progress file before the others.
void open_progress(const std::filesystem::path& file, int rank, int ranks) {
  g_ranks = ranks;
  g_progress_table.assign(static_cast<size_t>(ranks) * kProgressLine, ' ');
  g_progress_fd = ::open(file.c_str(), O_RDWR | O_CREAT, 0644);
  if (g_progress_fd < 0) throw std::runtime_error(file.string() + ": cannot open the progress file");
  if (rank == 0 && ftruncate(g_progress_fd, static_cast<off_t>(g_progress_table.size())) != 0)
    throw std::runtime_error(file.string() + ": cannot size the progress file");
  record_doing();
}

// The progress lines of the ranks that wrote one (async-signal-safe: read into the sized table).
size_t read_progress(int fd) {
  const ssize_t n = pread(fd, g_progress_table.data(), g_progress_table.size(), 0);
  return n > 0 ? static_cast<size_t>(n) : 0;
}

void write_all(const char* text, size_t n) { (void)!write(2, text, n); }
void write_text(const char* text) { write_all(text, std::strlen(text)); }
void write_number(long v) {
  char digits[24];
  int n = 0;
  do digits[sizeof digits - 1 - n++] = char('0' + v % 10), v /= 10; while (v > 0 && n < 20);
  write_all(digits + sizeof digits - n, static_cast<size_t>(n));
}
void write_progress_table(size_t bytes) {
  for (size_t at = 0; at + kProgressLine <= bytes; at += kProgressLine)
    if (g_progress_table[at] == 'r') {
      size_t end = at + kProgressLine - 1;
      while (end > at && g_progress_table[end - 1] == ' ') --end;
      write_all(g_progress_table.data() + at, end - at);
      write_text("\n");
    }
}

extern "C" void on_fatal_signal(int sig) {
  write_text("bgkmap: rank ");
  write_number(g_rank);
  write_text(" ended by signal ");
  write_number(sig);
  write_text(" while ");
  write_text(g_doing);
  write_text("\n");
  if (sig == SIGTERM && g_rank == 0 && g_progress_fd >= 0 && g_ranks > 1) {
    write_text("bgkmap: the job was ended (a rank died: mpirun names it); the last step each rank recorded:\n");
    write_progress_table(read_progress(g_progress_fd));
  }
  std::signal(sig, SIG_DFL);
  std::raise(sig);
}

// Fault injection for the tests: BGKMAP_KILL_RANK_AT=R:G[:SIGNAL] makes rank R send itself the
// signal (default SIGKILL, as a lost node) when it is about to map scan G.
void maybe_killed(int rank, uint64_t scan) {
  static const char* spec = std::getenv("BGKMAP_KILL_RANK_AT");
  if (!spec) return;
  int r = -1, sig = SIGKILL;
  unsigned long long g = 0;
  if (std::sscanf(spec, "%d:%llu:%d", &r, &g, &sig) >= 2 && r == rank && g == scan) std::raise(sig);
}

// The partition from every rank's footprint estimate (identical on every rank).
SpatialPartition partition_from(const TileCosts& costs, int ranks) {
  const std::vector<std::pair<uint64_t, double>> mine = costs.sorted();
  std::vector<uint64_t> my_codes(mine.size());
  std::vector<double> my_costs(mine.size());
  for (size_t i = 0; i < mine.size(); ++i) my_codes[i] = mine[i].first, my_costs[i] = mine[i].second;
  int my_count = static_cast<int>(mine.size());
  std::vector<int> counts(static_cast<size_t>(ranks)), displs(static_cast<size_t>(ranks));
  MPI_Allgather(&my_count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
  int total = 0;
  for (int r = 0; r < ranks; ++r) displs[static_cast<size_t>(r)] = total, total += counts[static_cast<size_t>(r)];
  std::vector<uint64_t> codes(static_cast<size_t>(total));
  std::vector<double> values(static_cast<size_t>(total));
  MPI_Allgatherv(my_codes.data(), my_count, MPI_UINT64_T, codes.data(), counts.data(), displs.data(), MPI_UINT64_T,
                 MPI_COMM_WORLD);
  MPI_Allgatherv(my_costs.data(), my_count, MPI_DOUBLE, values.data(), counts.data(), displs.data(), MPI_DOUBLE,
                 MPI_COMM_WORLD);
  TileCosts all;
  for (size_t i = 0; i < codes.size(); ++i) all.add(codes[i], values[i]);
  return SpatialPartition(ranks, all.sorted());
}

// The held-input records of global scans [0, scans), as a single-process build records them.
std::vector<HeldInput> held_up_to(HeldInputs& held, uint64_t& added, uint64_t scans,
                                  const std::vector<std::filesystem::path>& files,
                                  const std::vector<uint64_t>& scans_in_file) {
  uint64_t before = 0;
  for (size_t f = 0; f < files.size() && added < scans; ++f) {
    for (; added < scans && added < before + scans_in_file[f]; ++added) held.add(files, f, added - before);
    before += scans_in_file[f];
  }
  return held.records();
}

ShardManifest manifest_of(int ranks, uint64_t scans, const SpatialPartition& partition, uint64_t checkpoint_at,
                          std::vector<HeldInput> held) {
  ShardManifest m;
  m.ranks = ranks;
  m.scans = scans;
  m.partition = partition.first_codes();
  for (int r = 0; r < ranks; ++r) {
    m.shard_maps.push_back(shard_map_name(r, checkpoint_at));
    m.shard_orders.push_back(shard_order_name(r, checkpoint_at));
  }
  m.held = std::move(held);
  return m;
}

// The shard folder: --shards, else a resumed run's checkpoint folder, else the first output's
// name + ".shards". A resumed run continues in its checkpoint's folder.
std::filesystem::path shard_folder(const DistributedBuildRequest& req) {
  namespace fs = std::filesystem;
  if (!req.resume.empty()) {
    fs::path folder = fs::is_directory(req.resume) ? fs::path(req.resume) : fs::path(req.resume).parent_path();
    if (folder.empty()) folder = ".";
    std::error_code ec;
    if (!req.shards.empty() && !fs::equivalent(req.shards, folder, ec))
      throw std::runtime_error("--shards " + req.shards + " is not the folder of --resume " + req.resume +
                               ": a resumed run continues in its checkpoint's folder");
    return folder;
  }
  if (!req.shards.empty()) return req.shards;
  return fs::path(req.outputs.empty() ? "bgkmap" : req.outputs.front()) += ".shards";
}

// A resumed run shows where each rank of the interrupted one was.
void print_interrupted_progress(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line, lines;
  while (std::getline(in, line)) {
    line.erase(line.find_last_not_of(' ') + 1);
    if (line.rfind("rank ", 0) == 0) lines += "  " + line + "\n";
  }
  if (!lines.empty()) std::fprintf(stderr, "bgkmap: the interrupted run's last recorded steps:\n%s", lines.c_str());
}

void build(const DistributedBuildRequest& req, int rank, int ranks) {
  const Clock::time_point start = Clock::now();
  double fig[kFigureCount] = {};
  g_rank = rank;
  for (const int sig : {SIGTERM, SIGINT, SIGSEGV, SIGBUS, SIGFPE, SIGABRT}) std::signal(sig, on_fatal_signal);
  std::string context;  // what failed, for the one line
  try {
    const BuildParams& params = req.params;
    params.validate();
    const std::filesystem::path shard_dir = shard_folder(req);
    if (rank == 0) {
      for (const std::string& out : req.outputs) map_format_from_path(out), check_output_path(out);
      std::filesystem::create_directories(shard_dir);
      if (!req.resume.empty()) print_interrupted_progress(shard_dir / kShardProgressName);
      open_progress(shard_dir / kShardProgressName, rank, ranks);
    }
    MPI_Barrier(MPI_COMM_WORLD);  // rank 0 made the shard folder and its progress file
    if (rank != 0) open_progress(shard_dir / kShardProgressName, rank, ranks);
    ScanSource source({req.inputs.begin(), req.inputs.end()});
    const std::vector<std::filesystem::path>& files = source.files();
    BackendOptions backend = req.backend;
    if (backend.threads <= 0) {
      const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
      const int per_node = local ? std::max(1, std::atoi(local)) : 1;
      backend.threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / per_node);
    }

    // A resumed build: this rank's shard of the last complete checkpoint, and its partition.
    std::optional<ShardManifest> resumed;
    std::unique_ptr<Mapper> mapper;
    std::vector<uint32_t> created_by_scan;
    if (!req.resume.empty()) {
      context = "resuming from " + req.resume;
      resumed = read_manifest(req.resume);
      if (resumed->ranks != ranks)
        throw std::runtime_error("the checkpoint was written by " + std::to_string(resumed->ranks) +
                                 " ranks: resume it with mpirun -np " + std::to_string(resumed->ranks));
      const std::filesystem::path& folder = shard_dir;
      NativeMapFile shard = read_native_map_file(folder / resumed->shard_maps[static_cast<size_t>(rank)]);
      if (params_to_json(shard.map.params()) != params_to_json(params))
        throw std::runtime_error("the checkpoint was built with other parameters");
      created_by_scan = read_shard_order(folder / resumed->shard_orders[static_cast<size_t>(rank)]);
      if (created_by_scan.size() != shard.map.block_count())
        throw InputError(folder / resumed->shard_orders[static_cast<size_t>(rank)], "does not match its shard's blocks");
      mapper = std::make_unique<Mapper>(std::move(shard.map), make_integrator(backend));
    } else {
      mapper = std::make_unique<Mapper>(params, make_integrator(backend));
    }
    if (rank == 0 && !mapper->backend().note.empty())
      std::fprintf(stderr, "bgkmap: warning: %s\n", mapper->backend().note.c_str());
    const Grid grid = mapper->map().grid();
    const float support_m = params.kernel.support_radius_m(params.grid.resolution_m);

    // Pass 1 (a new build): the share's footprints, for the partition's cost estimate; every
    // rank also learns how many scans each file holds.
    Clock::time_point t = Clock::now();
    std::vector<uint64_t> scans_in_file;
    std::optional<SpatialPartition> partition;
    {
      ShareReader reader(files, ranks, resumed ? ranks : rank);  // resumed: count only
      TileCosts costs;
      Scan scan;
      uint64_t g = 0;
      ScanObservations obs;
      PreprocessCounts ignored;
      for (uint64_t read = 0;; ++read) {
        context.clear();
        set_doing("reading for the partition");
        if (!reader.next(scan, g)) break;
        if (read % kFootprintStride != 0) continue;  // every scan is read (a bad file fails here), some estimated
        context = "scan " + std::to_string(g);
        observations_from(prepare_scan(scan, params.preprocess), params.preprocess, obs, ignored);
        costs.add_scan(grid, obs);
      }
      scans_in_file = reader.scans_in_file();
      context = "partitioning";
      if (resumed) partition.emplace(resumed->partition);
      else partition.emplace(partition_from(costs, ranks));
    }
    if (partition->ranks() != ranks) throw std::runtime_error("the checkpoint's partition is not for this many ranks");
    fig[kEstimatedCost] = partition->estimated_costs().empty() ? 0.0 : partition->estimated_costs()[static_cast<size_t>(rank)];
    fig[kFootprintS] = seconds_since(t);

    // Rank 0 keeps the record of the scans held, for the checkpoints and the merged .bgk.
    HeldInputs held;
    uint64_t held_added = 0;
    const uint64_t first_scan = resumed ? resumed->scans : 0;
    if (rank == 0 && resumed) {
      context = "checking the inputs against the checkpoint";
      HeldInputs check(resumed->held);
      uint64_t matched = 0;
      for (const uint64_t n : check.match(files)) matched += n;
      if (matched != resumed->scans)
        throw std::runtime_error("the inputs do not hold the checkpoint's " + std::to_string(resumed->scans) +
                                 " scans (" + std::to_string(matched) + " match by content)");
      std::fprintf(stderr, "bgkmap: resuming from the checkpoint of %llu scans in %s\n",
                   static_cast<unsigned long long>(resumed->scans), shard_dir.string().c_str());
    }

    // Pass 2: rounds of K scans, scan first + j*K + r read by rank r; each rank maps them in order.
    ShareReader reader(files, ranks, rank, first_scan);
    ObservationRouter router;
    std::vector<std::vector<uint32_t>> hit_ids, end_ids;
    std::vector<char> send, recv;
    std::vector<int> send_counts(static_cast<size_t>(ranks)), send_displs(static_cast<size_t>(ranks)),
        recv_counts(static_cast<size_t>(ranks)), recv_displs(static_cast<size_t>(ranks));
    std::vector<std::vector<char>> parts(static_cast<size_t>(ranks));
    ScanObservations obs, received;
    PreprocessCounts preprocess;
    const auto keep = [&](const BlockKey& key) { return partition->owner(key) == rank; };
    bool reading = true;
    uint64_t done = first_scan;
    for (uint64_t round = 0;; ++round) {
      Scan scan;
      uint64_t g = 0;
      for (auto& part : parts) part.clear();
      int has_scan = 0;
      if (reading) {
        t = Clock::now();
        context.clear();
        set_doing("reading its next scan");
        reading = reader.next(scan, g);
        if (reading) {
          context = "scan " + std::to_string(g);
          if (scan.pose_covariance)
            throw std::invalid_argument("a pose uncertainty (poses with a covariance) is for a single-process build");
          set_doing("preparing scan " + std::to_string(g));
          observations_from(prepare_scan(scan, params.preprocess), params.preprocess, obs, preprocess);
          fig[kReadS] += seconds_since(t);
          fig[kScansRead] += 1;
          fig[kObservationsRead] += double(obs.hits.size() + obs.free_ends.size());
          t = Clock::now();
          router.route(grid, support_m, obs, *partition, hit_ids, end_ids);
          for (int r = 0; r < ranks; ++r) {
            const auto& h = hit_ids[static_cast<size_t>(r)];
            const auto& e = end_ids[static_cast<size_t>(r)];
            if (h.empty() && e.empty()) continue;
            pack(parts[static_cast<size_t>(r)], g, obs, h, e);
            fig[kObservationsSent] += double(h.size() + e.size());
          }
          fig[kRouteS] += seconds_since(t);
          has_scan = 1;
        } else {
          fig[kReadS] += seconds_since(t);
        }
      }
      int round_scans = 0;
      t = Clock::now();  // where a rank waits for the slowest one of the last round
      MPI_Allreduce(&has_scan, &round_scans, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
      fig[kWaitS] += seconds_since(t);
      if (round_scans == 0) break;

      context = "exchanging round " + std::to_string(round);
      set_doing(context);
      t = Clock::now();
      send.clear();
      for (int r = 0; r < ranks; ++r) {
        send_displs[static_cast<size_t>(r)] = static_cast<int>(send.size());
        send_counts[static_cast<size_t>(r)] = static_cast<int>(parts[static_cast<size_t>(r)].size());
        send.insert(send.end(), parts[static_cast<size_t>(r)].begin(), parts[static_cast<size_t>(r)].end());
      }
      MPI_Alltoall(send_counts.data(), 1, MPI_INT, recv_counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
      int recv_total = 0;
      for (int r = 0; r < ranks; ++r)
        recv_displs[static_cast<size_t>(r)] = recv_total, recv_total += recv_counts[static_cast<size_t>(r)];
      recv.resize(static_cast<size_t>(recv_total));
      MPI_Alltoallv(send.data(), send_counts.data(), send_displs.data(), MPI_CHAR, recv.data(), recv_counts.data(),
                    recv_displs.data(), MPI_CHAR, MPI_COMM_WORLD);
      fig[kExchangeS] += seconds_since(t);
      fig[kBytesSent] += double(send.size() - static_cast<size_t>(send_counts[static_cast<size_t>(rank)]));
      fig[kBytesReceived] += double(recv_total - recv_counts[static_cast<size_t>(rank)]);

      // Source rank order is global scan order within the round.
      for (int r = 0; r < ranks; ++r) {
        if (recv_counts[static_cast<size_t>(r)] == 0) continue;
        uint64_t scan_no = 0;
        unpack(recv.data() + recv_displs[static_cast<size_t>(r)], scan_no, received);
        context = "mapping scan " + std::to_string(scan_no);
        set_doing(context);
        maybe_killed(rank, scan_no);
        mapper->insert_observations(received, keep);
        created_by_scan.resize(mapper->block_count(), static_cast<uint32_t>(scan_no));
      }
      const uint64_t before = done;
      done += static_cast<uint64_t>(round_scans);

      // A checkpoint: every rank's shard under names of its own, then (all written) rank 0's
      // manifest naming them, renamed into place; only then are the last checkpoint's files removed.
      if (req.checkpoint_every > 0 && done / req.checkpoint_every > before / req.checkpoint_every) {
        context = "writing the checkpoint of " + std::to_string(done) + " scans";
        set_doing(context);
        write_shard(shard_dir, rank, mapper->map(), created_by_scan, done);
        MPI_Barrier(MPI_COMM_WORLD);
        if (rank == 0) {
          write_manifest(shard_dir / kShardManifestName,
                         manifest_of(ranks, done, *partition, done, held_up_to(held, held_added, done, files, scans_in_file)));
          remove_checkpoints(shard_dir, done);
        }
      }
    }

    context = "writing its shard";
    set_doing(context);
    t = Clock::now();
    const BgkMap& map = mapper->map();
    write_shard(shard_dir, rank, map, created_by_scan);
    fig[kWriteShardS] = seconds_since(t);
    const InsertTiming& timing = mapper->timing();
    fig[kInsertS] = timing.insert_s;
    fig[kBucketS] = timing.bucket_s;
    fig[kComputeS] = timing.compute_s;
    fig[kBlocks] = double(map.block_count());
    fig[kPeakRssMb] = peak_rss_mb();

    // Counts summed over ranks: preprocessing where the scans were read, integration where mapped.
    uint64_t local[11] = {preprocess.points_read, preprocess.dropped_nonfinite, preprocess.removed_by_downsampling,
                          preprocess.beyond_max_range, preprocess.hits, preprocess.beams,
                          mapper->counts().integrate.pairs_evaluated, mapper->counts().integrate.pairs_within_support,
                          mapper->counts().block_visits, preprocess.dropped_out_of_key_range,
                          preprocess.dropped_beyond_reach};
    uint64_t summed[11] = {};
    MPI_Reduce(local, summed, 11, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
    std::vector<double> figures(rank == 0 ? static_cast<size_t>(kFigureCount * ranks) : 0);
    MPI_Gather(fig, kFigureCount, MPI_DOUBLE, figures.data(), kFigureCount, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Barrier(MPI_COMM_WORLD);  // every shard is written

    if (rank == 0) {
      context = "merging the shards";
      set_doing(context);
      const std::vector<HeldInput> held_records = held_up_to(held, held_added, done, files, scans_in_file);
      write_manifest(shard_dir / kShardManifestName, manifest_of(ranks, done, *partition, 0, held_records));
      remove_checkpoints(shard_dir, 0);
      std::filesystem::remove(shard_dir / kShardProgressName);
      t = Clock::now();
      double merge_s = 0, write_s = 0;
      if (!req.outputs.empty()) {
        const BgkMap whole = merge_shards(shard_dir / kShardManifestName);
        merge_s = seconds_since(t);
        t = Clock::now();
        OutputBatch outputs;
        for (const std::string& out : req.outputs) {
          if (map_format_from_path(out) == MapFormat::kNative) write_native_map(out, whole, held_records);
          else write_map(out, whole);
        }
        outputs.commit();
        write_s = seconds_since(t);
      }
      if (!req.report.empty()) {
        nlohmann::json per_rank = nlohmann::json::array();
        for (int r = 0; r < ranks; ++r) {
          nlohmann::json one;
          for (int f = 0; f < kFigureCount; ++f) one[kFigureNames[f]] = figures[static_cast<size_t>(r * kFigureCount + f)];
          per_rank.push_back(one);
        }
        nlohmann::json inputs = nlohmann::json::array();
        for (const auto& f : files) inputs.push_back(f.string());
        nlohmann::json p = params_to_json(params);
        p["method"] = "bgkl";
        p["threads"] = backend.threads;
        p["backend"] = backend.backend;
        const nlohmann::json report = {
            {"params", p},
            {"inputs", inputs},
            {"outputs", req.outputs},
            {"shards", shard_dir.string()},
            {"ranks", ranks},
            {"resumed_from_scan", first_scan},
            {"counts",
             {{"scans", done},
              {"scans_already_held", first_scan},
              {"points_read", summed[0]},
              {"dropped_nonfinite", summed[1]},
              {"dropped_out_of_key_range", summed[9]},
              {"dropped_beyond_reach", summed[10]},
              {"removed_by_downsampling", summed[2]},
              {"beyond_max_range", summed[3]},
              {"hits", summed[4]},
              {"beams", summed[5]},
              {"pairs_evaluated", summed[6]},
              {"pairs_within_l", summed[7]},
              {"block_visits", summed[8]}}},
            {"timing", {{"merge_s", merge_s}, {"write_s", write_s}, {"total_s", seconds_since(start)}}},
            {"backend", {{"name", mapper->backend().name}, {"device", mapper->backend().device}}},
            {"per_rank", per_rank}};
        write_file_atomically(req.report, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
      }
      if (!req.quiet)
        std::fprintf(stderr, "bgkmap: %llu scans on %d ranks, %llu hits, %llu beams; shards in %s, %.3f s\n",
                     static_cast<unsigned long long>(done), ranks, static_cast<unsigned long long>(summed[4]),
                     static_cast<unsigned long long>(summed[5]), shard_dir.string().c_str(), seconds_since(start));
    }
  } catch (const std::exception& e) {
    abort_job(rank, context.empty() ? std::string(e.what()) : context + ": " + e.what());
  }
}

}  // namespace

void run_distributed_build(const DistributedBuildRequest& request) {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  build(request, rank, ranks);
  MPI_Finalize();
}

}  // namespace bgkmap
