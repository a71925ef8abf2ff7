// The MPI side of a distributed build. Every MPI call of the project is in this file.
#include "bgkmap/dist/distributed_build.hpp"

#include <mpi.h>
#include <sys/resource.h>
#include <fcntl.h>
#include <unistd.h>

#include <csignal>
#include <cerrno>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <thread>

#include "bgkmap/core/log.hpp"
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
  log_info("rank " + std::to_string(rank) + ": " + what);
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
  kObservationsSent, kObservationsRead, kBlocks, kPeakRssMb, kEstimatedCost, kFootprintS, kWaitS, kWriteMapS,
  kPairsEvaluated, kFigureCount
};
const char* const kFigureNames[kFigureCount] = {
    "scans_read", "read_s", "route_s", "exchange_s", "insert_s", "bucket_s", "compute_s", "write_shard_s",
    "bytes_sent", "bytes_received", "observations_sent", "observations_read", "blocks", "peak_rss_mb",
    "estimated_cost", "footprint_s", "wait_s", "write_map_s", "pairs_evaluated"};


// How many rounds a rank reads and sends ahead of the round it maps: it absorbs the ranks' round to
// round differences in mapping time, for a few scans' observations in memory.
constexpr uint64_t kLookaheadRounds = 8;
// The tag of the messages carrying scans' observations (the only point-to-point messages), and
// one no message carries (probed only to make MPI progress).
constexpr int kScanTag = 1;
constexpr int kNoMessageTag = 2;

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

// Fault injection for the tests (DistributedBuildRequest::kill_rank_at, "R:G[:SIGNAL]").
void maybe_killed(const std::string& spec, int rank, uint64_t scan) {
  if (spec.empty()) return;
  int r = -1, sig = SIGKILL;
  unsigned long long g = 0;
  if (std::sscanf(spec.c_str(), "%d:%llu:%d", &r, &g, &sig) >= 2 && r == rank && g == scan) std::raise(sig);
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

// The .bgk of the whole map, written by every rank at once: write_native_map's file of the
// single-process map, byte for byte, without any rank holding more than its own blocks. The file's
// blocks are in the order one process creates them (by creating scan, then key); rank 0 merges
// the ranks' (scan, key) lists, each in that order; each rank makes its records and sends rank 0
// their lengths and checksums, rank 0 tells each rank where its records go and combines the
// checksums into the file's. `held` and the file's head and end are rank 0's.
class BgkWrittenTogether {
 public:
  BgkWrittenTogether(const BgkMap& map, const std::vector<uint32_t>& created_by_scan, int rank, int ranks)
      : map_(map), rank_(rank), ranks_(ranks) {
    mine_.resize(map.block_count());
    for (uint32_t s = 0; s < mine_.size(); ++s) mine_[s] = s;
    std::sort(mine_.begin(), mine_.end(), [&](uint32_t a, uint32_t b) {
      return block_file_order(created_by_scan[a], map.key_of_slot(a), created_by_scan[b], map.key_of_slot(b));
    });
    place(created_by_scan);
  }

  // Collective: every rank calls it for the same target, in the same order.
  // write_file's failures name the target (write_path_atomically's own already do).
  void write(const std::filesystem::path& target, const std::vector<HeldInput>& held) {
    const auto write_named = [&](const std::filesystem::path& temp, const std::vector<HeldInput>* inputs) {
      try {
        write_file(temp, inputs);
      } catch (const std::runtime_error& e) {
        throw std::runtime_error(target.string() + ": " + e.what());
      }
    };
    if (rank_ == 0) {
      write_path_atomically(target, [&](const std::filesystem::path& temp) { write_named(temp, &held); });
    } else {
      write_named({}, nullptr);
    }
  }

 private:
  // Each rank's (scan, key) list to rank 0, which merges them and keeps the owner of every file
  // position; every rank learns the map's block count.
  void place(const std::vector<uint32_t>& created_by_scan) {
    std::vector<uint32_t> words;  // per block: scan, key x, y, z (as u32)
    words.reserve(4 * mine_.size());
    for (const uint32_t s : mine_) {
      const BlockKey& k = map_.key_of_slot(s);
      words.insert(words.end(), {created_by_scan[s], static_cast<uint32_t>(k.x), static_cast<uint32_t>(k.y),
                                 static_cast<uint32_t>(k.z)});
    }
    const int my_words = static_cast<int>(words.size());
    std::vector<int> counts(static_cast<size_t>(ranks_)), displs(static_cast<size_t>(ranks_));
    MPI_Gather(&my_words, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<uint32_t> all;
    if (rank_ == 0) {
      size_t at = 0;
      for (int r = 0; r < ranks_; ++r) displs[size_t(r)] = static_cast<int>(at), at += size_t(counts[size_t(r)]);
      all.resize(at);
    }
    MPI_Gatherv(words.data(), my_words, MPI_UINT32_T, all.data(), counts.data(), displs.data(), MPI_UINT32_T, 0,
                MPI_COMM_WORLD);
    if (rank_ == 0) {
      // A K-way merge: the front of each rank's list, smallest (scan, key) first.
      struct Front {
        uint32_t scan;
        BlockKey key;
        int rank;
      };
      const auto later = [](const Front& a, const Front& b) { return block_file_order(b.scan, b.key, a.scan, a.key); };
      std::vector<size_t> next(static_cast<size_t>(ranks_), 0);
      const auto front = [&](int r) {
        const uint32_t* w = all.data() + displs[size_t(r)] + 4 * next[size_t(r)];
        return Front{w[0], BlockKey{static_cast<int32_t>(w[1]), static_cast<int32_t>(w[2]), static_cast<int32_t>(w[3])}, r};
      };
      std::vector<Front> heap;
      for (int r = 0; r < ranks_; ++r)
        if (counts[size_t(r)] > 0) heap.push_back(front(r));
      std::make_heap(heap.begin(), heap.end(), later);
      const size_t total = all.size() / 4;
      if (total > std::numeric_limits<uint32_t>::max()) throw std::runtime_error("the map has more than 2^32 blocks");
      owner_.reserve(total);
      while (!heap.empty()) {
        std::pop_heap(heap.begin(), heap.end(), later);
        const int r = heap.back().rank;
        heap.pop_back();
        owner_.push_back(r);
        if (4 * ++next[size_t(r)] < size_t(counts[size_t(r)])) {
          heap.push_back(front(r));
          std::push_heap(heap.begin(), heap.end(), later);
        }
      }
    }
    uint64_t blocks = owner_.size();
    MPI_Bcast(&blocks, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    blocks_ = blocks;
  }

  // Every rank makes its records for their lengths and checksums (and again to write them: holding
  // them would take memory in proportion to the map); rank 0 lays them out and makes the file at
  // `temp` (its head), every rank writes its records, rank 0 the end. A rank that fails says why;
  // every rank then throws.
  void write_file(const std::filesystem::path& temp, const std::vector<HeldInput>* held) {
    std::vector<uint64_t> lengths(mine_.size());  // this rank's records, in mine_ order
    std::vector<uint32_t> crcs(mine_.size());
    std::string record;
    for (size_t i = 0; i < mine_.size(); ++i) {
      record.clear();
      lengths[i] = append_native_map_record(record, map_, mine_[i]);
      crcs[i] = native_map_crc(record.data(), record.size());
    }
    uint64_t records_bytes = 0;
    uint32_t records_crc = 0;
    const std::vector<uint64_t> offsets = lay_out(lengths, crcs, records_bytes, records_crc);

    std::string path = temp.string(), error;
    uint64_t head_bytes = 0;
    if (rank_ == 0) {
      try {
        const std::string head = native_map_head(map_.params(), map_.cells_per_block(), blocks_, records_bytes, *held);
        head_bytes = head.size();
        const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd < 0) throw std::runtime_error(std::string("cannot open for writing (") + std::strerror(errno) + ")");
        const bool written = write_at(fd, head.data(), head.size(), 0);
        const int err = errno;
        ::close(fd);
        if (!written) throw std::runtime_error(std::string("write failed (") + std::strerror(err) + ")");
      } catch (const std::exception& e) {
        error = e.what();
        path.clear();
      }
    }
    broadcast(path);
    MPI_Bcast(&head_bytes, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    if (path.empty()) throw std::runtime_error(rank_ == 0 ? error : "rank 0 could not create the file");

    if (error.empty()) error = write_records(path, head_bytes, lengths, offsets);
    int failed = error.empty() ? 0 : 1, any_failed = 0;
    MPI_Allreduce(&failed, &any_failed, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (any_failed) throw std::runtime_error(failed ? error : "another rank could not write its blocks");
    if (rank_ != 0) return;
    const std::string tail = native_map_tail(records_crc);
    const int fd = ::open(path.c_str(), O_WRONLY);
    const bool ok = fd >= 0 && write_at(fd, tail.data(), tail.size(), head_bytes + records_bytes);
    const int err = errno;
    if (fd >= 0) ::close(fd);
    if (!ok) throw std::runtime_error(std::string("write failed (") + std::strerror(err) + ")");
  }

  // Each rank's record lengths and checksums (mine_ order) to rank 0, which puts the records end
  // to end in file order; back: the file offset (past the head) of each of this rank's records.
  // Rank 0 also gets the records' total length and their combined checksum.
  std::vector<uint64_t> lay_out(const std::vector<uint64_t>& lengths, const std::vector<uint32_t>& crcs,
                                uint64_t& records_bytes, uint32_t& records_crc) const {
    const int n = static_cast<int>(lengths.size());
    std::vector<int> counts(static_cast<size_t>(ranks_)), displs(static_cast<size_t>(ranks_));
    MPI_Gather(&n, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
    std::vector<uint64_t> all_lengths, all_offsets;
    std::vector<uint32_t> all_crcs;
    if (rank_ == 0) {
      for (int r = 0, at = 0; r < ranks_; ++r) displs[size_t(r)] = at, at += counts[size_t(r)];
      all_lengths.resize(blocks_), all_crcs.resize(blocks_), all_offsets.resize(blocks_);
    }
    MPI_Gatherv(lengths.data(), n, MPI_UINT64_T, all_lengths.data(), counts.data(), displs.data(), MPI_UINT64_T, 0,
                MPI_COMM_WORLD);
    MPI_Gatherv(crcs.data(), n, MPI_UINT32_T, all_crcs.data(), counts.data(), displs.data(), MPI_UINT32_T, 0,
                MPI_COMM_WORLD);
    if (rank_ == 0) {
      std::vector<uint32_t> file_crcs;  // in file order
      std::vector<uint64_t> file_lengths;
      file_crcs.reserve(blocks_), file_lengths.reserve(blocks_);
      std::vector<int> next(displs);
      uint64_t at = 0;
      for (const int r : owner_) {
        const size_t k = size_t(next[size_t(r)]++);
        all_offsets[k] = at;
        at += all_lengths[k];
        file_crcs.push_back(all_crcs[k]), file_lengths.push_back(all_lengths[k]);
      }
      records_bytes = at;
      records_crc = native_map_records_crc(file_crcs, file_lengths);
    }
    std::vector<uint64_t> offsets(lengths.size());
    MPI_Scatterv(all_offsets.data(), counts.data(), displs.data(), MPI_UINT64_T, offsets.data(), n, MPI_UINT64_T, 0,
                 MPI_COMM_WORLD);
    return offsets;
  }

  // This rank's records at their offsets, runs of records adjacent in the file in one write each.
  std::string write_records(const std::string& path, uint64_t head_bytes, const std::vector<uint64_t>& lengths,
                            const std::vector<uint64_t>& offsets) const {
    const int fd = ::open(path.c_str(), O_WRONLY);
    if (fd < 0) return std::string("cannot open for writing (") + std::strerror(errno) + ")";
    // Runs of at most 256 KiB: much longer runs write slower (docs/SCALE.md, the .bgk written together).
    constexpr uint64_t kRun = uint64_t(256) << 10;
    std::string run;
    run.reserve(kRun);
    uint64_t run_at = 0;  // the run's file offset
    bool ok = true;
    for (size_t i = 0; i < lengths.size() && ok; ++i) {
      if (!run.empty() && (offsets[i] != run_at + run.size() || run.size() >= kRun)) {
        ok = write_at(fd, run.data(), run.size(), head_bytes + run_at);
        run.clear();
      }
      if (run.empty()) run_at = offsets[i];
      append_native_map_record(run, map_, mine_[i]);
    }
    if (ok && !run.empty()) ok = write_at(fd, run.data(), run.size(), head_bytes + run_at);
    const int err = errno;
    ::close(fd);
    return ok ? std::string() : std::string("write failed (") + std::strerror(err) + ")";
  }

  static bool write_at(int fd, const char* data, size_t n, uint64_t offset) {
    while (n > 0) {
      const ssize_t w = ::pwrite(fd, data, n, static_cast<off_t>(offset));
      if (w < 0 && errno == EINTR) continue;
      if (w == 0) errno = EIO;  // no progress and no error: say so rather than a stale errno
      if (w <= 0) return false;
      data += w, n -= size_t(w), offset += uint64_t(w);
    }
    return true;
  }

  static void broadcast(std::string& text) {
    uint64_t n = text.size();
    MPI_Bcast(&n, 1, MPI_UINT64_T, 0, MPI_COMM_WORLD);
    text.resize(n);
    MPI_Bcast(text.data(), static_cast<int>(n), MPI_CHAR, 0, MPI_COMM_WORLD);
  }

  const BgkMap& map_;
  int rank_, ranks_;
  std::vector<uint32_t> mine_;      // this rank's slots in file order
  std::vector<int> owner_;          // rank 0: the rank of each position
  uint64_t blocks_ = 0;             // in the whole map
};

// While a rank maps, a thread of it enters MPI every millisecond, so that the messages it sends and
// receives flow meanwhile: Open MPI moves a message larger than its eager limit only inside MPI
// calls of both sides, and a rank mapping a scan makes none for a tenth of a second or more. Needs
// MPI_THREAD_MULTIPLE (without it, nothing is started and messages flow between scans).
class ProgressThread {
 public:
  explicit ProgressThread(bool multiple) {
    if (multiple) thread_ = std::thread([this] { run(); });
  }
  ~ProgressThread() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  ProgressThread(const ProgressThread&) = delete;
  ProgressThread& operator=(const ProgressThread&) = delete;

 private:
  void run() {
    while (!stop_) {
      int ignored = 0;
      MPI_Iprobe(MPI_ANY_SOURCE, kNoMessageTag, MPI_COMM_WORLD, &ignored, MPI_STATUS_IGNORE);
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

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

// The interrupted run's progress file, while a run resuming it has not passed its checks.
constexpr const char* kInterruptedProgressName = "progress.interrupted";

// Whether `--resume` (rank 0 decides, for every rank) names the folder of a run killed before its
// first checkpoint: its progress file and no manifest. That run is begun again from the first
// scan, as a single-process --resume of a checkpoint not yet written is. A folder with neither is
// refused, naming it.
bool resume_has_no_checkpoint(const DistributedBuildRequest& req, const std::filesystem::path& shard_dir, int rank) {
  int fresh = 0;
  if (rank == 0) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (fs::is_directory(req.resume, ec) && !fs::exists(shard_dir / kShardManifestName, ec)) {
      if (!fs::exists(shard_dir / kShardProgressName, ec) && !fs::exists(shard_dir / kInterruptedProgressName, ec))
        throw InputError(req.resume, "holds no checkpoint (no manifest.json) and no interrupted run's progress file: "
                                     "give the shard folder of the interrupted run, or build without --resume");
      fresh = 1;
      log_info("no checkpoint in " + shard_dir.string() + " yet (the interrupted run wrote none): building from the first scan");
    }
  }
  MPI_Bcast(&fresh, 1, MPI_INT, 0, MPI_COMM_WORLD);
  return fresh != 0;
}

// A resumed run shows where each rank of the interrupted one was.
void print_interrupted_progress(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::string line, lines;
  while (std::getline(in, line)) {
    line.erase(line.find_last_not_of(' ') + 1);
    if (line.rfind("rank ", 0) == 0) lines += "  " + line + "\n";
  }
  if (!lines.empty()) log_info("the interrupted run's last recorded steps:\n" + lines.substr(0, lines.size() - 1));
}

// The backend of one rank: threads 0 takes the node's cores divided among its ranks.
BackendOptions rank_backend(BackendOptions backend) {
  if (backend.threads <= 0) {
    const char* local = std::getenv("OMPI_COMM_WORLD_LOCAL_SIZE");
    const int per_node = local ? std::max(1, std::atoi(local)) : 1;
    backend.threads = std::max(1, static_cast<int>(std::thread::hardware_concurrency()) / per_node);
  }
  return backend;
}

// Counts summed over ranks: preprocessing where the scans were read, integration where mapped.
enum SummedCount {
  kPointsRead, kDroppedNonfinite, kRemovedByDownsampling, kBeyondMaxRange, kHits, kBeams, kPairs, kPairsWithinL,
  kBlockVisits, kDroppedOutOfKeyRange, kDroppedBeyondReach, kSummedCount
};

// One rank's part of the build, in the order the steps run; every rank makes the same collective
// MPI calls in the same order. context() names the step that failed, for the one line.
class RankBuild {
 public:
  // `thread_multiple`: MPI may be called from several threads at once.
  RankBuild(const DistributedBuildRequest& req, int rank, int ranks, bool thread_multiple)
      : req_(req), params_(req.params), rank_(rank), ranks_(ranks), thread_multiple_(thread_multiple) {}

  void run() {
    open_shard_folder();
    decide_outputs();
    MPI_Barrier(MPI_COMM_WORLD);  // rank 0 made the shard folder and its progress file
    if (rank_ != 0) open_progress(shard_dir_ / kShardProgressName, rank_, ranks_);
    files_ = ScanSource({req_.inputs.begin(), req_.inputs.end()}).files();
    backend_ = rank_backend(req_.backend);
    open_map();
    partition_pass();
    check_resumed_inputs();
    map_rounds();
    finish();
  }
  const std::string& context() const { return context_; }

 private:
  // Per rank, the bytes of one round's scan sent to it (this rank's own part included).
  struct Outgoing {
    uint64_t round = 0;
    std::vector<std::vector<char>> parts;
    std::vector<MPI_Request> requests;
  };
  struct Incoming {
    std::vector<char> bytes;
    MPI_Request request;
  };

  void open_shard_folder() {
    params_.validate();
    shard_dir_ = shard_folder(req_);
    from_checkpoint_ = !req_.resume.empty() && !resume_has_no_checkpoint(req_, shard_dir_, rank_);
    if (rank_ != 0) return;
    for (const std::string& out : req_.outputs) check_map_output(out);
    std::filesystem::create_directories(shard_dir_);
    if (!req_.resume.empty()) {
      // Kept until a resumed run gets past its checks, so that one refused (other flags, other
      // inputs) does not replace the interrupted run's steps with its own.
      std::error_code ec;
      if (!std::filesystem::exists(shard_dir_ / kInterruptedProgressName, ec))
        std::filesystem::copy_file(shard_dir_ / kShardProgressName, shard_dir_ / kInterruptedProgressName, ec);
      print_interrupted_progress(shard_dir_ / kInterruptedProgressName);
    }
    open_progress(shard_dir_ / kShardProgressName, rank_, ranks_);
  }

  // The .bgk outputs are written by all ranks together unless another format needs the whole
  // map on rank 0 (then merged from the shards) or one is written in place (a device). The final
  // shards are kept when --shards names their folder, when resuming, or for that merge.
  void decide_outputs() {
    int together_flag = 0;
    if (rank_ == 0) {
      together_flag = req_.outputs.empty() ? 0 : 1;
      for (const std::string& out : req_.outputs)
        if (map_format_from_path(out) != MapFormat::kNative || written_in_place(out)) together_flag = 0;
    }
    MPI_Bcast(&together_flag, 1, MPI_INT, 0, MPI_COMM_WORLD);
    together_ = together_flag != 0;
    keep_shards_ = !req_.shards.empty() || !req_.resume.empty() || !together_;
  }

  // A resumed build: this rank's shard of the last complete checkpoint, and its partition.
  void open_map() {
    if (from_checkpoint_) {
      context_ = "resuming from " + req_.resume;
      resumed_ = read_manifest(req_.resume);
      if (resumed_->ranks != ranks_)
        throw std::runtime_error("the checkpoint was written by " + std::to_string(resumed_->ranks) +
                                 " ranks: resume it with mpirun -np " + std::to_string(resumed_->ranks));
      const std::filesystem::path& folder = shard_dir_;
      const size_t r = static_cast<size_t>(rank_);
      NativeMapFile shard = read_native_map_file(folder / resumed_->shard_maps[r]);
      if (params_to_json(shard.map.params()) != params_to_json(params_))
        throw std::runtime_error("the checkpoint was built with other parameters");
      created_by_scan_ = read_shard_order(folder / resumed_->shard_orders[r]);
      if (created_by_scan_.size() != shard.map.block_count())
        throw InputError(folder / resumed_->shard_orders[r], "does not match its shard's blocks");
      check_shard_blocks_owned(shard.map, SpatialPartition(resumed_->partition), rank_, folder / resumed_->shard_maps[r]);
      mapper_ = std::make_unique<Mapper>(std::move(shard.map), make_integrator(backend_));
    } else {
      mapper_ = std::make_unique<Mapper>(params_, make_integrator(backend_));
    }
    if (rank_ == 0 && !mapper_->backend().note.empty())
      log_warning(mapper_->backend().note);
    grid_.emplace(mapper_->map().grid());
  }

  // Pass 1 (a new build): the share's footprints, for the partition's cost estimate; every
  // rank also learns how many scans each file holds.
  void partition_pass() {
    const Clock::time_point t = Clock::now();
    ShareReader reader(files_, ranks_, resumed_ ? ranks_ : rank_);  // resumed: count only
    TileCosts costs;
    Scan scan;
    uint64_t g = 0;
    ScanObservations obs;
    PreprocessCounts ignored;
    // Every scan of the share is estimated (a sample leaves the ranks' work unequal: docs/DISTRIBUTED.md).
    for (;;) {
      context_.clear();
      set_doing("reading for the partition");
      if (!reader.next(scan, g)) break;
      context_ = "scan " + std::to_string(g);
      observations_from(prepare_scan(scan, params_.preprocess), params_.preprocess, obs, ignored);
      costs.add_scan(*grid_, obs);
    }
    scans_in_file_ = reader.scans_in_file();
    total_scans_ = reader.scans();
    context_ = "partitioning";
    if (resumed_) partition_.emplace(resumed_->partition);
    else partition_.emplace(partition_from(costs, ranks_));
    if (partition_->ranks() != ranks_) throw std::runtime_error("the checkpoint's partition is not for this many ranks");
    const std::vector<double>& estimated = partition_->estimated_costs();
    fig_[kEstimatedCost] = estimated.empty() ? 0.0 : estimated[static_cast<size_t>(rank_)];
    fig_[kFootprintS] = seconds_since(t);
  }

  // Rank 0 keeps the record of the scans held, for the checkpoints and the merged .bgk.
  void check_resumed_inputs() {
    first_scan_ = resumed_ ? resumed_->scans : 0;
    if (rank_ == 0 && resumed_) {
      context_ = "checking the inputs against the checkpoint";
      HeldInputs check(resumed_->held);
      uint64_t matched = 0;
      for (const uint64_t n : check.match(files_)) matched += n;
      if (matched != resumed_->scans)
        throw std::runtime_error("the inputs do not hold the checkpoint's " + std::to_string(resumed_->scans) +
                                 " scans (" + std::to_string(matched) + " match by content)");
      log_info("resuming from the checkpoint of " + std::to_string(resumed_->scans) + " scans in " + shard_dir_.string());
    }
    if (!req_.resume.empty()) {
      MPI_Barrier(MPI_COMM_WORLD);  // every rank took its shard: the progress file now records this run
      std::error_code ignored;
      if (rank_ == 0) std::filesystem::remove(shard_dir_ / kInterruptedProgressName, ignored);
    }
  }

  uint64_t scan_of(uint64_t round, int r) const { return first_scan_ + round * uint64_t(ranks_) + uint64_t(r); }

  // Pass 2: round j holds scans first + j*K + r, scan first + j*K + r read by rank r. Each rank
  // reads, routes and sends its scans up to kLookaheadRounds rounds ahead of the round it maps
  // (one message to every other rank per round, in round order), so that a rank waits only for
  // a scan not yet sent, not for the slowest rank of every round; it maps each round's scans in
  // global scan order.
  void map_rounds() {
    rounds_ = total_scans_ > first_scan_ ? (total_scans_ - first_scan_ + uint64_t(ranks_) - 1) / uint64_t(ranks_) : 0;
    reader_.emplace(files_, ranks_, rank_, first_scan_);
    incoming_.resize(static_cast<size_t>(ranks_));
    matched_.assign(static_cast<size_t>(ranks_), 0);
    done_ = first_scan_;
    std::optional<ProgressThread> progress;
    if (ranks_ > 1) progress.emplace(thread_multiple_);
    for (uint64_t round = 0; round < rounds_; ++round) {
      for (; sent_ < rounds_ && sent_ < round + kLookaheadRounds; ++sent_) send_round(sent_);
      map_round(round);
      forget_delivered(round);
      const uint64_t before = done_;
      done_ = std::min(total_scans_, scan_of(round + 1, 0));
      if (req_.checkpoint_every > 0 && done_ / req_.checkpoint_every > before / req_.checkpoint_every)
        write_checkpoint();
    }
    const Clock::time_point t = Clock::now();
    for (Outgoing& out : outgoing_)
      MPI_Waitall(static_cast<int>(out.requests.size()), out.requests.data(), MPI_STATUSES_IGNORE);
    outgoing_.clear();
    progress.reset();
    fig_[kExchangeS] += seconds_since(t);
  }

  // Reads this rank's scan of `round`, routes its observations and sends each rank its part.
  void send_round(uint64_t round) {
    Outgoing& out = outgoing_.emplace_back();
    out.round = round;
    out.parts.resize(static_cast<size_t>(ranks_));
    const uint64_t expected = scan_of(round, rank_);
    if (expected >= total_scans_) return;
    Clock::time_point t = Clock::now();
    context_.clear();
    set_doing("reading its next scan");
    Scan scan;
    uint64_t g = 0;
    if (!reader_->next(scan, g) || g != expected)
      throw std::runtime_error("scan " + std::to_string(expected) + ": the inputs changed while being read");
    context_ = "scan " + std::to_string(g);
    if (scan.pose_covariance)
      throw std::invalid_argument("a pose uncertainty (poses with a covariance) is for a single-process build");
    set_doing("preparing scan " + std::to_string(g));
    observations_from(prepare_scan(scan, params_.preprocess), params_.preprocess, obs_, preprocess_);
    fig_[kReadS] += seconds_since(t);
    fig_[kScansRead] += 1;
    fig_[kObservationsRead] += double(obs_.hits.size() + obs_.free_ends.size());
    t = Clock::now();
    const float support_m = params_.kernel.support_radius_m(params_.grid.resolution_m);
    router_.route(*grid_, support_m, obs_, *partition_, hit_ids_, end_ids_);
    for (int r = 0; r < ranks_; ++r) {
      const auto& h = hit_ids_[static_cast<size_t>(r)];
      const auto& e = end_ids_[static_cast<size_t>(r)];
      if (h.empty() && e.empty()) continue;
      pack(out.parts[static_cast<size_t>(r)], g, obs_, h, e);
      fig_[kObservationsSent] += double(h.size() + e.size());
    }
    fig_[kRouteS] += seconds_since(t);
    t = Clock::now();
    for (int r = 0; r < ranks_; ++r) {
      if (r == rank_) continue;
      const std::vector<char>& part = out.parts[static_cast<size_t>(r)];
      MPI_Request request;
      MPI_Isend(part.data(), static_cast<int>(part.size()), MPI_CHAR, r, kScanTag, MPI_COMM_WORLD, &request);
      out.requests.push_back(request);
      fig_[kBytesSent] += double(part.size());
    }
    fig_[kExchangeS] += seconds_since(t);
  }

  // Posts the receive of source s's next round's message; without `wait`, only if it has come.
  bool receive_next(int s, bool wait) {
    uint64_t& next = matched_[static_cast<size_t>(s)];
    if (next >= rounds_ || scan_of(next, s) >= total_scans_) return false;
    int found = 1;
    MPI_Message message;
    MPI_Status status;
    if (wait) MPI_Mprobe(s, kScanTag, MPI_COMM_WORLD, &message, &status);
    else MPI_Improbe(s, kScanTag, MPI_COMM_WORLD, &found, &message, &status);
    if (!found) return false;
    int bytes = 0;
    MPI_Get_count(&status, MPI_CHAR, &bytes);
    Incoming& in = incoming_[static_cast<size_t>(s)].emplace_back();
    in.bytes.resize(static_cast<size_t>(bytes));
    MPI_Imrecv(in.bytes.data(), bytes, MPI_CHAR, &message, &in.request);
    fig_[kBytesReceived] += double(bytes);
    ++next;
    return true;
  }

  // Maps the round's scans in global order, each rank's part of them received (or its own).
  void map_round(uint64_t round) {
    const Outgoing& own = outgoing_[static_cast<size_t>(round - outgoing_.front().round)];
    const auto keep = [&](const BlockKey& key) { return partition_->owner(key) == rank_; };
    for (int r = 0; r < ranks_ && scan_of(round, r) < total_scans_; ++r) {
      const uint64_t g = scan_of(round, r);
      const std::vector<char>* part = &own.parts[static_cast<size_t>(r)];
      if (r != rank_) {
        context_ = "receiving scan " + std::to_string(g);
        set_doing("waiting for scan " + std::to_string(g));
        const Clock::time_point t = Clock::now();
        std::deque<Incoming>& from = incoming_[static_cast<size_t>(r)];
        if (from.empty()) receive_next(r, /*wait=*/true);
        MPI_Wait(&from.front().request, MPI_STATUS_IGNORE);
        fig_[kWaitS] += seconds_since(t);
        arrived_ = std::move(from.front().bytes);
        from.pop_front();
        part = &arrived_;
      }
      if (!part->empty()) {  // else nothing of this scan reaches this rank's blocks
        uint64_t scan_no = 0;
        unpack(part->data(), scan_no, received_);
        if (scan_no != g) throw std::logic_error("rank " + std::to_string(r) + " sent scan " + std::to_string(scan_no));
        context_ = "mapping scan " + std::to_string(g);
        set_doing(context_);
        maybe_killed(req_.kill_rank_at, rank_, g);
        mapper_->insert_observations(received_, keep);
        created_by_scan_.resize(mapper_->block_count(), static_cast<uint32_t>(g));
      }
      // Take in the messages that have come (a large one flows only once its receive is posted,
      // while its sender next enters MPI: posting early lets it flow during the next scans).
      const Clock::time_point t = Clock::now();
      for (int s = 0; s < ranks_; ++s)
        if (s != rank_)
          while (receive_next(s, /*wait=*/false)) {
          }
      fig_[kExchangeS] += seconds_since(t);
    }
  }

  // Rounds mapped here whose messages have left (a send completes once its receiver took it).
  void forget_delivered(uint64_t round) {
    while (!outgoing_.empty() && outgoing_.front().round <= round) {
      int delivered = 0;
      std::vector<MPI_Request>& requests = outgoing_.front().requests;
      MPI_Testall(static_cast<int>(requests.size()), requests.data(), &delivered, MPI_STATUSES_IGNORE);
      if (!delivered) break;
      outgoing_.pop_front();
    }
  }

  // A checkpoint: every rank's shard under names of its own, then (all written) rank 0's
  // manifest naming them, renamed into place; only then are the last checkpoint's files removed.
  void write_checkpoint() {
    context_ = "writing the checkpoint of " + std::to_string(done_) + " scans";
    set_doing(context_);
    write_shard(shard_dir_, rank_, mapper_->map(), created_by_scan_, done_);
    ++checkpoints_written_;
    MPI_Barrier(MPI_COMM_WORLD);
    if (rank_ == 0) {
      write_manifest(shard_dir_ / kShardManifestName,
                     manifest_of(ranks_, done_, *partition_, done_,
                                 held_up_to(held_, held_added_, done_, files_, scans_in_file_)));
      remove_checkpoints(shard_dir_, done_);
    }
  }

  // The final shard, the counts and figures to rank 0, the outputs, the report.
  void finish() {
    context_.clear();
    if (keep_shards_) {
      context_ = "writing its shard";
      set_doing(context_);
      const Clock::time_point t = Clock::now();
      write_shard(shard_dir_, rank_, mapper_->map(), created_by_scan_);
      fig_[kWriteShardS] = seconds_since(t);
    }
    const InsertTiming& timing = mapper_->timing();
    fig_[kInsertS] = timing.insert_s;
    fig_[kBucketS] = timing.bucket_s;
    fig_[kComputeS] = timing.compute_s;
    fig_[kBlocks] = double(mapper_->map().block_count());
    fig_[kPairsEvaluated] = double(mapper_->counts().integrate.pairs_evaluated);
    sum_counts();
    std::vector<double> figures(rank_ == 0 ? static_cast<size_t>(kFigureCount * ranks_) : 0);
    if (keep_shards_) MPI_Barrier(MPI_COMM_WORLD);  // every final shard is written (the .bgk written together has its own)
    // The -o outputs: .bgk files written by all ranks together, else merged from the shards on rank 0.
    if (rank_ == 0) held_records_ = held_up_to(held_, held_added_, done_, files_, scans_in_file_);
    if (together_) write_outputs_together();
    fig_[kPeakRssMb] = peak_rss_mb();
    MPI_Gather(fig_, kFigureCount, MPI_DOUBLE, figures.data(), kFigureCount, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    if (rank_ != 0) return;
    tidy_shard_folder();
    if (!together_ && !req_.outputs.empty()) write_merged_outputs();
    if (!req_.report.empty()) {
      const nlohmann::json report = report_json(figures);
      write_file_atomically(req_.report, [&](std::ostream& out) { out << report.dump(2) << '\n'; });
    }
    if (req_.quiet) return;
    char seconds[32];
    std::snprintf(seconds, sizeof seconds, "%.3f s", seconds_since(start_));
    log_info(std::to_string(done_) + " scans on " + std::to_string(ranks_) + " ranks, " +
             std::to_string(summed_[kHits]) + " hits, " + std::to_string(summed_[kBeams]) + " beams" +
             (keep_shards_ ? "; shards in " + shard_dir_.string() : std::string()) + ", " + seconds);
  }

  // The counts of every rank, summed on rank 0.
  void sum_counts() {
    const BuildCounts& counts = mapper_->counts();
    uint64_t local[kSummedCount] = {preprocess_.points_read, preprocess_.dropped_nonfinite,
                                    preprocess_.removed_by_downsampling, preprocess_.beyond_max_range,
                                    preprocess_.hits, preprocess_.beams, counts.integrate.pairs_evaluated,
                                    counts.integrate.pairs_within_support, counts.block_visits,
                                    preprocess_.dropped_out_of_key_range, preprocess_.dropped_beyond_reach};
    MPI_Reduce(local, summed_, kSummedCount, MPI_UINT64_T, MPI_SUM, 0, MPI_COMM_WORLD);
  }

  void write_outputs_together() {
    context_ = "writing the outputs";
    set_doing(context_);
    Clock::time_point t = Clock::now();
    BgkWrittenTogether writer(mapper_->map(), created_by_scan_, rank_, ranks_);
    merge_s_ = seconds_since(t);
    t = Clock::now();
    OutputBatch outputs;
    for (const std::string& out : req_.outputs) writer.write(out, held_records_);
    if (rank_ == 0) outputs.commit();
    write_s_ = seconds_since(t);
    fig_[kWriteMapS] = write_s_;
  }

  // Rank 0: the final manifest when the shards stay, and no checkpoint or progress file left.
  void tidy_shard_folder() {
    if (keep_shards_)
      write_manifest(shard_dir_ / kShardManifestName, manifest_of(ranks_, done_, *partition_, 0, held_records_));
    else if (checkpoints_written_ > 0)
      std::filesystem::remove(shard_dir_ / kShardManifestName);  // it names this run's checkpoints
    remove_checkpoints(shard_dir_, 0);
    std::filesystem::remove(shard_dir_ / kShardProgressName);
    if (!keep_shards_) {
      std::error_code ignored;
      std::filesystem::remove(shard_dir_, ignored);  // only if nothing else is in it
    }
  }

  // Rank 0: the outputs from the whole map merged from the shards.
  void write_merged_outputs() {
    context_ = "merging the shards";
    set_doing(context_);
    Clock::time_point t = Clock::now();
    const BgkMap whole = merge_shards(shard_dir_ / kShardManifestName);
    merge_s_ = seconds_since(t);
    t = Clock::now();
    context_ = "writing the outputs";
    set_doing(context_);
    OutputBatch outputs;
    for (const std::string& out : req_.outputs) {
      if (map_format_from_path(out) == MapFormat::kNative) write_native_map(out, whole, held_records_);
      else write_map(out, whole, "bgkl", req_.ot_values);
    }
    outputs.commit();
    write_s_ = seconds_since(t);
  }

  // Rank 0: the JSON report; `figures` holds every rank's, rank by rank.
  nlohmann::json report_json(const std::vector<double>& figures) const {
    nlohmann::json per_rank = nlohmann::json::array();
    for (int r = 0; r < ranks_; ++r) {
      nlohmann::json one;
      for (int f = 0; f < kFigureCount; ++f) one[kFigureNames[f]] = figures[static_cast<size_t>(r * kFigureCount + f)];
      per_rank.push_back(one);
    }
    nlohmann::json inputs = nlohmann::json::array();
    for (const auto& f : files_) inputs.push_back(f.string());
    nlohmann::json p = params_to_json(params_);
    p["method"] = "bgkl";
    p["threads"] = backend_.threads;
    p["backend"] = backend_.backend;
    const uint64_t* summed = summed_;
    return {{"params", p},
            {"inputs", inputs},
            {"outputs", req_.outputs},
            {"shards", keep_shards_ ? shard_dir_.string() : ""},
            {"ranks", ranks_},
            {"resumed_from_scan", first_scan_},
            {"counts",
             {{"scans", done_},
              {"scans_already_held", first_scan_},
              {"points_read", summed[kPointsRead]},
              {"dropped_nonfinite", summed[kDroppedNonfinite]},
              {"dropped_out_of_key_range", summed[kDroppedOutOfKeyRange]},
              {"dropped_beyond_reach", summed[kDroppedBeyondReach]},
              {"removed_by_downsampling", summed[kRemovedByDownsampling]},
              {"beyond_max_range", summed[kBeyondMaxRange]},
              {"hits", summed[kHits]},
              {"beams", summed[kBeams]},
              {"pairs_evaluated", summed[kPairs]},
              {"pairs_within_l", summed[kPairsWithinL]},
              {"block_visits", summed[kBlockVisits]}}},
            {"timing", {{"merge_s", merge_s_}, {"write_s", write_s_}, {"total_s", seconds_since(start_)}}},
            {"backend", {{"name", mapper_->backend().name}, {"device", mapper_->backend().device}}},
            {"per_rank", per_rank}};
  }

  const DistributedBuildRequest& req_;
  const BuildParams& params_;
  const int rank_, ranks_;
  const bool thread_multiple_;
  const Clock::time_point start_ = Clock::now();
  double fig_[kFigureCount] = {};
  uint64_t summed_[kSummedCount] = {};
  std::string context_;  // what failed, for the one line

  std::filesystem::path shard_dir_;
  bool from_checkpoint_ = false, together_ = false, keep_shards_ = false;
  std::vector<std::filesystem::path> files_;
  BackendOptions backend_;
  std::optional<ShardManifest> resumed_;
  std::unique_ptr<Mapper> mapper_;
  std::optional<Grid> grid_;
  std::vector<uint32_t> created_by_scan_;
  std::vector<uint64_t> scans_in_file_;
  uint64_t total_scans_ = 0, first_scan_ = 0;
  std::optional<SpatialPartition> partition_;
  HeldInputs held_;
  uint64_t held_added_ = 0;
  std::vector<HeldInput> held_records_;

  // Pass 2.
  uint64_t rounds_ = 0, sent_ = 0, done_ = 0;  // sent_: rounds whose scan of this rank is read and sent
  std::optional<ShareReader> reader_;
  ObservationRouter router_;
  std::vector<std::vector<uint32_t>> hit_ids_, end_ids_;
  std::deque<Outgoing> outgoing_;  // rounds sent and not yet both mapped and delivered, oldest first
  std::vector<std::deque<Incoming>> incoming_;  // per source rank, the messages matched and being received
  std::vector<uint64_t> matched_;               // per source: rounds matched
  std::vector<char> arrived_;
  ScanObservations obs_, received_;
  PreprocessCounts preprocess_;
  int checkpoints_written_ = 0;
  double merge_s_ = 0, write_s_ = 0;
};

void build(const DistributedBuildRequest& req, int rank, int ranks, bool thread_multiple) {
  g_rank = rank;
  if (req.report_fatal_signals)
    for (const int sig : {SIGTERM, SIGINT, SIGSEGV, SIGBUS, SIGFPE, SIGABRT}) std::signal(sig, on_fatal_signal);
  RankBuild job(req, rank, ranks, thread_multiple);
  try {
    job.run();
  } catch (const std::exception& e) {
    abort_job(rank, job.context().empty() ? std::string(e.what()) : job.context() + ": " + e.what());
  }
}

}  // namespace

void run_distributed_build(const DistributedBuildRequest& request) {
  int provided = 0;
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_MULTIPLE, &provided);
  int rank = 0, ranks = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &ranks);
  build(request, rank, ranks, provided >= MPI_THREAD_MULTIPLE);
  MPI_Finalize();
}

}  // namespace bgkmap
