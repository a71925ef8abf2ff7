// The MPI side of a distributed build. Every MPI call of the project is in this file.
#include "bgkmap/dist/distributed_build.hpp"

#include <mpi.h>
#include <sys/resource.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
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
  ShareReader(std::vector<std::filesystem::path> files, int ranks, int rank)
      : files_(std::move(files)), ranks_(ranks), rank_(rank), scans_in_file_(files_.size(), 0) {}

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
  bool owns(uint64_t g) const { return g % static_cast<uint64_t>(ranks_) == static_cast<uint64_t>(rank_); }

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
  kObservationsSent, kObservationsRead, kBlocks, kPeakRssMb, kEstimatedCost, kFootprintS, kFigureCount
};
const char* const kFigureNames[kFigureCount] = {
    "scans_read", "read_s", "route_s", "exchange_s", "insert_s", "bucket_s", "compute_s", "write_shard_s",
    "bytes_sent", "bytes_received", "observations_sent", "observations_read", "blocks", "peak_rss_mb",
    "estimated_cost", "footprint_s"};

void build(const DistributedBuildRequest& req, int rank, int ranks) {
  const Clock::time_point start = Clock::now();
  double fig[kFigureCount] = {};
  std::string context = "starting";  // what this rank was doing, for the message if it fails
  try {
    const BuildParams& params = req.params;
    params.validate();
    const std::filesystem::path shard_dir =
        !req.shards.empty() ? std::filesystem::path(req.shards)
                            : std::filesystem::path(req.outputs.empty() ? "bgkmap" : req.outputs.front()) += ".shards";
    if (rank == 0) {
      for (const std::string& out : req.outputs) map_format_from_path(out), check_output_path(out);
      std::filesystem::create_directories(shard_dir);
    }
    ScanSource source({req.inputs.begin(), req.inputs.end()});
    BackendOptions backend = req.backend;
    if (backend.threads <= 0) {
      const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
      const int per_node = local ? std::max(1, std::atoi(local)) : 1;
      backend.threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / per_node);
    }
    Mapper mapper(params, make_integrator(backend));
    if (rank == 0 && !mapper.backend().note.empty())
      std::fprintf(stderr, "bgkmap: warning: %s\n", mapper.backend().note.c_str());
    const Grid& grid = mapper.map().grid();
    const float support_m = params.kernel.support_radius_m(params.grid.resolution_m);
    MPI_Barrier(MPI_COMM_WORLD);  // rank 0 made the shard folder

    // Pass 1: the share's footprints, for the partition's cost estimate.
    Clock::time_point t = Clock::now();
    TileCosts costs;
    {
      ShareReader reader(source.files(), ranks, rank);
      Scan scan;
      uint64_t g = 0;
      ScanObservations obs;
      PreprocessCounts ignored;
      for (;;) {
        context = "";
        if (!reader.next(scan, g)) break;
        context = "scan " + std::to_string(g);
        observations_from(prepare_scan(scan, params.preprocess), params.preprocess, obs, ignored);
        costs.add_scan(grid, obs);
      }
    }
    context = "partitioning";
    const std::vector<std::pair<uint64_t, double>> mine = costs.sorted();
    std::vector<uint64_t> my_codes(mine.size());
    std::vector<double> my_costs(mine.size());
    for (size_t i = 0; i < mine.size(); ++i) my_codes[i] = mine[i].first, my_costs[i] = mine[i].second;
    int my_count = static_cast<int>(mine.size());
    std::vector<int> counts(static_cast<size_t>(ranks)), displs(static_cast<size_t>(ranks));
    MPI_Allgather(&my_count, 1, MPI_INT, counts.data(), 1, MPI_INT, MPI_COMM_WORLD);
    int total_tiles = 0;
    for (int r = 0; r < ranks; ++r) displs[static_cast<size_t>(r)] = total_tiles, total_tiles += counts[static_cast<size_t>(r)];
    std::vector<uint64_t> all_codes(static_cast<size_t>(total_tiles));
    std::vector<double> all_costs(static_cast<size_t>(total_tiles));
    MPI_Allgatherv(my_codes.data(), my_count, MPI_UINT64_T, all_codes.data(), counts.data(), displs.data(),
                   MPI_UINT64_T, MPI_COMM_WORLD);
    MPI_Allgatherv(my_costs.data(), my_count, MPI_DOUBLE, all_costs.data(), counts.data(), displs.data(), MPI_DOUBLE,
                   MPI_COMM_WORLD);
    std::vector<std::pair<uint64_t, double>> merged(static_cast<size_t>(total_tiles));
    for (size_t i = 0; i < merged.size(); ++i) merged[i] = {all_codes[i], all_costs[i]};
    std::stable_sort(merged.begin(), merged.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    size_t unique = 0;
    for (size_t i = 0; i < merged.size(); ++i) {
      if (unique > 0 && merged[unique - 1].first == merged[i].first) merged[unique - 1].second += merged[i].second;
      else merged[unique++] = merged[i];
    }
    merged.resize(unique);
    const SpatialPartition partition(ranks, merged);
    fig[kEstimatedCost] = partition.estimated_costs()[static_cast<size_t>(rank)];
    fig[kFootprintS] = seconds_since(t);

    // Pass 2: rounds of K scans, scan j*K + r read by rank r; each rank maps them in order.
    ShareReader reader(source.files(), ranks, rank);
    ObservationRouter router;
    std::vector<std::vector<uint32_t>> hit_ids, end_ids;
    std::vector<char> send, recv;
    std::vector<int> send_counts(static_cast<size_t>(ranks)), send_displs(static_cast<size_t>(ranks)),
        recv_counts(static_cast<size_t>(ranks)), recv_displs(static_cast<size_t>(ranks));
    std::vector<std::vector<char>> parts(static_cast<size_t>(ranks));
    std::vector<uint32_t> created_by_scan;
    ScanObservations obs, received;
    PreprocessCounts preprocess;
    const auto keep = [&](const BlockKey& key) { return partition.owner(key) == rank; };
    bool reading = true;
    for (uint64_t round = 0;; ++round) {
      Scan scan;
      uint64_t g = 0;
      for (auto& part : parts) part.clear();
      int has_scan = 0;
      if (reading) {
        t = Clock::now();
        context = "";
        reading = reader.next(scan, g);
        if (reading) {
          context = "scan " + std::to_string(g);
          observations_from(prepare_scan(scan, params.preprocess), params.preprocess, obs, preprocess);
          fig[kReadS] += seconds_since(t);
          fig[kScansRead] += 1;
          fig[kObservationsRead] += double(obs.hits.size() + obs.free_ends.size());
          t = Clock::now();
          router.route(grid, support_m, obs, partition, backend.threads, hit_ids, end_ids);
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
      int any = 0;
      MPI_Allreduce(&has_scan, &any, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
      if (!any) break;

      context = "exchanging round " + std::to_string(round);
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
        mapper.insert_observations(received, keep);
        created_by_scan.resize(mapper.block_count(), static_cast<uint32_t>(scan_no));
      }
    }

    context = "writing its shard";
    t = Clock::now();
    const BgkMap& map = mapper.map();
    write_shard(shard_dir, rank, map, created_by_scan);
    fig[kWriteShardS] = seconds_since(t);
    const InsertTiming& timing = mapper.timing();
    fig[kInsertS] = timing.insert_s;
    fig[kBucketS] = timing.bucket_s;
    fig[kComputeS] = timing.compute_s;
    fig[kBlocks] = double(map.block_count());
    fig[kPeakRssMb] = peak_rss_mb();

    // Counts summed over ranks: preprocessing where the scans were read, integration where mapped.
    uint64_t local[9] = {preprocess.points_read, preprocess.dropped_nonfinite, preprocess.removed_by_downsampling,
                         preprocess.beyond_max_range, preprocess.hits, preprocess.beams,
                         mapper.counts().integrate.pairs_evaluated, mapper.counts().integrate.pairs_within_support,
                         mapper.counts().block_visits};
    uint64_t summed[9] = {};
    MPI_Reduce(local, summed, 9, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
    std::vector<double> figures(rank == 0 ? static_cast<size_t>(kFigureCount * ranks) : 0);
    MPI_Gather(fig, kFigureCount, MPI_DOUBLE, figures.data(), kFigureCount, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    MPI_Barrier(MPI_COMM_WORLD);  // every shard is written

    if (rank == 0) {
      context = "merging the shards";
      // The scans the map holds, as a single-process build records them.
      Scan scan;
      uint64_t g = 0;
      HeldInputs held;
      uint64_t scans = 0;
      {
        // Counting scans needs only multi-scan files read; .pcd files count one each.
        ShareReader counter(source.files(), ranks, ranks);  // owns no scan: reads nothing but multi-scan files
        while (counter.next(scan, g)) {
        }
        scans = counter.scans();
        const auto& per_file = counter.scans_in_file();
        for (size_t f = 0; f < per_file.size(); ++f)
          for (uint64_t s = 0; s < per_file[f]; ++s) held.add(source.files(), f, s);
      }
      ShardManifest manifest;
      manifest.ranks = ranks;
      manifest.scans = scans;
      manifest.partition = partition.first_codes();
      for (int r = 0; r < ranks; ++r) {
        manifest.shard_maps.push_back(shard_map_name(r));
        manifest.shard_orders.push_back(shard_order_name(r));
      }
      manifest.held = held.records();
      write_manifest(shard_dir / kShardManifestName, manifest);
      t = Clock::now();
      double merge_s = 0, write_s = 0;
      if (!req.outputs.empty()) {
        const BgkMap whole = merge_shards(shard_dir / kShardManifestName);
        merge_s = seconds_since(t);
        t = Clock::now();
        OutputBatch outputs;
        for (const std::string& out : req.outputs) {
          if (map_format_from_path(out) == MapFormat::kNative) write_native_map(out, whole, held.records());
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
        nlohmann::json files = nlohmann::json::array();
        for (const auto& f : source.files()) files.push_back(f.string());
        nlohmann::json p = params_to_json(params);
        p["method"] = "bgkl";
        p["threads"] = backend.threads;
        p["backend"] = backend.backend;
        const nlohmann::json report = {
            {"params", p},
            {"inputs", files},
            {"outputs", req.outputs},
            {"shards", shard_dir.string()},
            {"ranks", ranks},
            {"counts",
             {{"scans", scans},
              {"points_read", summed[0]},
              {"dropped_nonfinite", summed[1]},
              {"removed_by_downsampling", summed[2]},
              {"beyond_max_range", summed[3]},
              {"hits", summed[4]},
              {"beams", summed[5]},
              {"pairs_evaluated", summed[6]},
              {"pairs_within_l", summed[7]},
              {"block_visits", summed[8]}}},
            {"timing", {{"merge_s", merge_s}, {"write_s", write_s}, {"total_s", seconds_since(start)}}},
            {"backend", {{"name", mapper.backend().name}, {"device", mapper.backend().device}}},
            {"per_rank", per_rank}};
        write_file_atomically(req.report, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
      }
      if (!req.quiet)
        std::fprintf(stderr, "bgkmap: %llu scans on %d ranks, %llu hits, %llu beams; shards in %s, %.3f s\n",
                     static_cast<unsigned long long>(scans), ranks, static_cast<unsigned long long>(summed[4]),
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
