#include "bgkmap/integrate/opencl_integrator.hpp"

#include <algorithm>
#include <array>
#include <cstdio>
#include <omp.h>
#include <utility>
#include <vector>

#include "bgkmap/core/log.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "integrate/beam_rows_8.hpp"
#include "device_pool.hpp"
#include "launch_plan.hpp"
#include "opencl_runtime.hpp"

namespace bgkmap {

namespace opencl_detail {
namespace {

// Observation bytes one launch may take when the caller sets no bound: large enough that a
// scan of 100k points is one or two launches, small enough for any device's single allocation.
constexpr size_t kDefaultLaunchBytes = size_t(64) << 20;
// Some drivers take global sizes as 32-bit numbers.
constexpr size_t kMaxGlobalSize = size_t(1) << 31;

size_t largest_power_of_two_at_most(size_t n) {
  size_t p = 1;
  while (p * 2 <= n) p *= 2;
  return p;
}

size_t smallest_power_of_two_at_least(size_t n) {
  size_t p = 1;
  while (p < n) p *= 2;
  return p;
}

// One launch input (jobs, hits, beams or beam rows) of one set.
struct LaunchInput {
  cl::Buffer device;             // what the kernel reads
  cl::Buffer staging;            // staged transfers: pinned host memory, mapped for its whole life
  void* staging_host = nullptr;  // where the host gathers into it
  size_t capacity = 0;           // records
};

// The launch inputs in the kernel's argument order.
enum LaunchInputIndex : size_t { kJobs, kHits, kBeams, kBeamRows, kLaunchInputs };

// One set of launch inputs. Two sets alternate, so the host fills one while the device reads the
// other; a set is refilled only after the kernel that read it is done.
struct LaunchBuffers {
  std::array<LaunchInput, kLaunchInputs> inputs;
  cl::Buffer counts;
  cl::Event kernel_done;              // the last kernel that read this set
  cl::Event counts_copied;            // its pair counts are in counts_host
  std::vector<cl_ulong> counts_host;  // per job of that launch: pairs evaluated, pairs within support
  size_t pending_jobs = 0;            // jobs of that launch whose counts are not added yet
};

// Whether launch inputs go through pinned staging memory and a copy (see InputTransfer).
bool stages_inputs(OpenClOptions::InputTransfer transfer, const OpenClDeviceInfo& device) {
  if (transfer == OpenClOptions::InputTransfer::kAuto) return device.type != "CPU";
  return transfer == OpenClOptions::InputTransfer::kStaged;
}

// Host threads for bucketing the next scan while the device works. A CPU device (PoCL) runs its
// work-groups on the host's cores, so one thread (more would take cores from PoCL: docs/DESIGN.md,
// "Back ends"). A GPU leaves the cores idle: all that the CPU path would use.
int host_threads_beside(const OpenClDeviceInfo& device, int cpu_threads) {
  if (device.type == "CPU") return 1;
  return cpu_threads > 0 ? cpu_threads : omp_get_max_threads();
}

// The kernel for 8^3 blocks with the sparse kernel (see OpenClOptions::RowsPerWorkItem).
enum class EightCubeKernel { kRuns, kPairs, kWhole };
EightCubeKernel eight_cube_kernel(OpenClOptions::RowsPerWorkItem rows, const OpenClDeviceInfo& device) {
  using Rows = OpenClOptions::RowsPerWorkItem;
  if (rows == Rows::kAuto) rows = device.type == "CPU" ? Rows::kWholeBlock : Rows::kOneRow;
  return rows == Rows::kWholeBlock ? EightCubeKernel::kWhole
                                   : rows == Rows::kTwoRows ? EightCubeKernel::kPairs : EightCubeKernel::kRuns;
}

// Work-items of bgk_block_sparse_pairs: the 32 row pairs of an 8^3 block.
constexpr size_t kRowPairs = 32;

class OpenClIntegrator final : public Integrator {
 public:
  OpenClIntegrator(std::shared_ptr<const DeviceProgram> program, const OpenClOptions& options, int cpu_threads)
      : program_(std::move(program)),
        cpu_threads_(cpu_threads),
        host_threads_(host_threads_beside(program_->info, cpu_threads)),
        staged_(stages_inputs(options.input_transfer, program_->info)),
        // Profiled: the report gives the kernels' device time beside the host's waiting.
        compute_(program_->context, program_->device, CL_QUEUE_PROFILING_ENABLE),
        transfer_(program_->context, program_->device),
        sparse_kernel_(program_->program, "bgk_block_sparse"),
        box_kernel_(program_->program, "bgk_block_box"),
        pairs_kernel_(program_->program, "bgk_block_sparse_pairs"),
        whole_kernel_(program_->program, "bgk_block_sparse_whole"),
        gather_kernel_(program_->program, "bgk_pool_gather"),
        scatter_kernel_(program_->program, "bgk_pool_scatter"),
        decay_kernel_(program_->program, "bgk_pool_decay"),
        pool_(program_->context,
              options.max_pool_bytes > 0 ? std::min<size_t>(options.max_pool_bytes, program_->info.max_allocation_bytes)
                                         : program_->info.max_allocation_bytes,
              !staged_) {
    const size_t launch_bytes =
        std::min<size_t>(options.max_launch_bytes > 0 ? options.max_launch_bytes : kDefaultLaunchBytes,
                         program_->info.max_allocation_bytes);
    group_limit_ = largest_power_of_two_at_most(
        std::min({kMaxGroupSize, program_->info.max_work_group_size,
                  program_->device.getInfo<CL_DEVICE_MAX_WORK_ITEM_SIZES>().at(0),
                  sparse_kernel_.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(program_->device),
                  box_kernel_.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(program_->device)}));
    eight_cube_ = eight_cube_kernel(options.rows_per_work_item, program_->info);
    if (eight_cube_ == EightCubeKernel::kPairs &&
        (pairs_kernel_.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(program_->device) < kRowPairs ||
         group_limit_ < kRowPairs))
      eight_cube_ = EightCubeKernel::kRuns;
    limits_.max_hits = std::max<size_t>(1, launch_bytes / sizeof(LocalHit));
    limits_.max_beams = std::max<size_t>(1, launch_bytes / sizeof(LocalBeam));
    limits_.max_jobs = std::max<size_t>(1, std::min(launch_bytes / sizeof(DeviceJob), kMaxGlobalSize / group_limit_));
  }

  ~OpenClIntegrator() override {
    try {
      compute_.finish();
      for (LaunchBuffers& set : sets_)
        for (LaunchInput& input : set.inputs)
          if (input.staging_host) transfer_.enqueueUnmapMemObject(input.staging, input.staging_host);
      transfer_.finish();
    } catch (const cl::Error&) {
      // Nothing left to save: the map was read back or the error was reported already.
    }
  }

  BackendInfo info() const override {
    if (cpu_) {
      BackendInfo b = cpu_->info();
      b.note = note_;
      return b;
    }
    // threads: bucketing; the device brings its own parallelism.
    return backend_info(DeviceKind::kOpenCl,
                        program_->info.full_name() + " (" + program_->info.type + ", " +
                            std::to_string(program_->info.compute_units) + " compute units, " +
                            program_->info.version + ")",
                        host_threads_, note_);
  }

  // Runs the map's kernel once on a scratch block: some drivers (PoCL) compile the kernel for
  // each work-group size at its first launch, which would otherwise land in the first scan.
  void prepare(const BgkMap& map) override {
    if (cpu_ || map_) return;
    try {
      const size_t cells = static_cast<size_t>(map.cells_per_block());
      std::vector<Cell> scratch_cells(cells, Cell{0.0f, 0.0f});
      DeviceJob job{0, 0, 0, 0, 0};  // no observations: the kernel adds zeros
      const cl::Context& context = program_->context;
      cl::Buffer pool(context, CL_MEM_READ_WRITE | CL_MEM_COPY_HOST_PTR, cells * sizeof(Cell), scratch_cells.data());
      cl::Buffer jobs(context, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, sizeof job, &job);
      cl::Buffer observations(context, CL_MEM_READ_ONLY, sizeof(LocalBeam));
      cl::Buffer counts(context, CL_MEM_WRITE_ONLY, 2 * sizeof(cl_ulong));
      enqueue_kernel(map, map.params().kernel.sigma0, pool, jobs, observations, observations, observations, counts, 1,
                     nullptr, nullptr);
      compute_.finish();
      pool_.prepare_slot_copies(cells);
    } catch (const cl::Error& e) {
      switch_to_cpu(std::string("refused a first launch (") + e.what() + ": " + cl_error_name(e.err()) +
                    "); the CPU path builds the map");
    }
  }

  void integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map, IntegrateStats& stats) override {
    ++scans_;
    if (cpu_) return cpu_->integrate(obs, buckets, map, stats);
    size_t pieces_launched = 0;
    try {
      plan_launches(buckets, limits_, pieces_, launches_);
      adopt(map);
      take_host_changes(map);
      host_current_ = false;
      for (const Launch& launch : launches_) {
        enqueue_launch(buckets, launch, map, map.params().kernel.sigma0 * obs.kernel_weight, stats);
        pieces_launched = launch.first_piece + launch.piece_count;
      }
    } catch (const cl::Error& e) {
      fall_back(map, stats,
                std::string("the device refused the work (") + e.what() + ": " + cl_error_name(e.err()) + ")");
      cpu_->integrate(obs, remaining_work(buckets, pieces_launched), map, stats);
    } catch (const DeviceMemoryExhausted& e) {
      fall_back(map, stats, e.what());
      cpu_->integrate(obs, remaining_work(buckets, pieces_launched), map, stats);
    }
  }

  // The device decays its own copy of the blocks (bgk_pool_decay, the host's arithmetic), queued
  // before the scan's kernels: no copy either way, no wait.
  void decay_blocks(BgkMap& map, const std::vector<uint32_t>& slots, const std::vector<float>& factors,
                    IntegrateStats& stats) override {
    if (slots.empty()) return;
    if (cpu_) return cpu_->decay_blocks(map, slots, factors, stats);
    try {
      adopt(map);
      take_host_changes(map);
      host_current_ = false;
      pool_.decay_slots(compute_, map, slots, factors, decay_kernel_);
    } catch (const cl::Error& e) {
      fall_back(map, stats,
                std::string("the device refused the work (") + e.what() + ": " + cl_error_name(e.err()) + ")");
      cpu_->decay_blocks(map, slots, factors, stats);
    } catch (const DeviceMemoryExhausted& e) {
      fall_back(map, stats, e.what());
      cpu_->decay_blocks(map, slots, factors, stats);
    }
  }

  void finish(IntegrateStats& stats) override {
    if (cpu_) return;
    wait_for_device("finishing the queued scans");
    for (LaunchBuffers& set : sets_) collect_stats(set, stats);
  }

  int idle_host_threads() const override { return cpu_threads_ > 0 ? cpu_threads_ : omp_get_max_threads(); }

 private:
  // The cells of `slots` (null: all) back to the host, once the device is done with them.
  void copy_to_host(BgkMap& map, const std::vector<uint32_t>* slots) override {
    if (cpu_ || host_current_ || &map != map_) return;
    const char* doing = slots ? "copying cells back" : "copying the map back";
    wait_for_device(doing);
    try {
      take_host_changes(map);
      if (slots) pool_.read_slots(compute_, map, *slots, gather_kernel_);
      else pool_.read_back(compute_, map);
    } catch (const cl::Error& e) {
      throw device_lost(doing, e);
    }
    if (!slots) host_current_ = true;
  }

  // Every cell (null) or those of `slots` are newer on the host: the device takes them first.
  void host_changed(const std::vector<uint32_t>* slots) override {
    if (!slots) {
      take_host_cells_ = true;
      host_slots_.clear();
    } else if (!cpu_ && !take_host_cells_) {
      host_slots_.insert(host_slots_.end(), slots->begin(), slots->end());
    }
  }

  // Gathers the launch into one set's inputs (mapped in place, or staged and copied) and queues
  // the kernel behind their transfer.
  // sigma0: the kernel's scale for these observations (KernelParams::sigma0 times their weight).
  void enqueue_launch(const ScanBuckets& buckets, const Launch& launch, const BgkMap& map, float sigma0,
                      IntegrateStats& stats) {
    LaunchBuffers& set = sets_[next_set_];
    next_set_ = 1 - next_set_;
    collect_stats(set, stats);  // waits for the set's previous kernel, and so for its input copies

    const size_t jobs = launch.piece_count;
    // 8^3 blocks under the sparse kernel: each beam's reachable rows, from the host (see the kernel).
    const bool host_rows = host_row_bits(map);
    RowReach8 row_reach = RowReach8::make(map.grid().resolution(), map.params().kernel.ell_m);
    if (map.params().preprocess.planar) row_reach.layer_rows = uint64_t{0xFF} << (8 * map.layer_local_z());
    const std::array<size_t, kLaunchInputs> records{jobs, launch.hits, launch.beams, host_rows ? launch.beams : 0};
    const std::array<size_t, kLaunchInputs> limits{limits_.max_jobs, limits_.max_hits, limits_.max_beams,
                                                   limits_.max_beams};
    const std::array<size_t, kLaunchInputs> record_bytes{sizeof(DeviceJob), sizeof(LocalHit), sizeof(LocalBeam),
                                                         sizeof(uint64_t)};
    for (size_t i = 0; i < kLaunchInputs; ++i) ensure_capacity(set.inputs[i], records[i], limits[i], record_bytes[i]);
    const size_t job_capacity = set.inputs[kJobs].capacity;
    if (set.counts_host.size() < 2 * job_capacity) {
      set.counts = cl::Buffer(program_->context, CL_MEM_WRITE_ONLY, 2 * job_capacity * sizeof(cl_ulong));
      set.counts_host.resize(2 * job_capacity);
    }

    // Mapped inputs: blocking maps on the transfer queue, which waits for nothing the compute
    // queue is doing. Staged inputs: the set's pinned memory, free once its last kernel is done.
    std::array<void*, kLaunchInputs> host{};
    std::array<void*, kLaunchInputs> mapped{};
    std::vector<cl::Event> transferred;
    try {
      for (size_t i = 0; i < kLaunchInputs; ++i) {
        const size_t bytes = records[i] * record_bytes[i];
        if (bytes == 0) continue;
        host[i] = staged_ ? set.inputs[i].staging_host
                          : (mapped[i] = transfer_.enqueueMapBuffer(set.inputs[i].device, CL_TRUE,
                                                                    CL_MAP_WRITE_INVALIDATE_REGION, 0, bytes));
      }
      gather_launch(buckets, pieces_, launch, static_cast<DeviceJob*>(host[kJobs]), static_cast<LocalHit*>(host[kHits]),
                    static_cast<LocalBeam*>(host[kBeams]), host_rows ? &row_reach : nullptr,
                    static_cast<uint64_t*>(host[kBeamRows]), host_threads_);
      for (size_t i = 0; i < kLaunchInputs; ++i) {
        if (!host[i]) continue;
        cl::Event done;
        if (staged_) {
          transfer_.enqueueWriteBuffer(set.inputs[i].device, CL_FALSE, 0, records[i] * record_bytes[i], host[i],
                                       nullptr, &done);
        } else {
          transfer_.enqueueUnmapMemObject(set.inputs[i].device, mapped[i], nullptr, &done);
          mapped[i] = nullptr;
        }
        transferred.push_back(done);
      }
      transfer_.flush();
    } catch (...) {
      for (size_t i = 0; i < kLaunchInputs; ++i)
        if (mapped[i]) transfer_.enqueueUnmapMemObject(set.inputs[i].device, mapped[i]);
      throw;
    }

    enqueue_kernel(map, sigma0, pool_.buffer(), set.inputs[kJobs].device, set.inputs[kHits].device, set.inputs[kBeams].device,
                   set.inputs[kBeamRows].device, set.counts, jobs, &transferred, &set.kernel_done);
    compute_.enqueueReadBuffer(set.counts, CL_FALSE, 0, 2 * jobs * sizeof(cl_ulong), set.counts_host.data(), nullptr,
                               &set.counts_copied);
    set.pending_jobs = jobs;
    compute_.flush();
  }

  // Grows `input` to hold `count` records (power-of-two steps, at most `limit`). Called only once
  // the set's last kernel is done, so nothing still reads the buffers it replaces.
  void ensure_capacity(LaunchInput& input, size_t count, size_t limit, size_t record_bytes) {
    count = std::max<size_t>(count, 1);  // a zero-sized buffer is not allowed, even if unused
    if (count <= input.capacity) return;
    const size_t grown = std::min(limit, smallest_power_of_two_at_least(count));
    const size_t bytes = grown * record_bytes;
    const cl::Context& context = program_->context;
    if (staged_) {
      if (input.staging_host) transfer_.enqueueUnmapMemObject(input.staging, input.staging_host);
      input.staging_host = nullptr;
      input.capacity = 0;
      input.staging = cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_ALLOC_HOST_PTR, bytes);
      input.staging_host = transfer_.enqueueMapBuffer(input.staging, CL_TRUE, CL_MAP_WRITE, 0, bytes);
      input.device = cl::Buffer(context, CL_MEM_READ_ONLY, bytes);
    } else {
      input.device = cl::Buffer(context, CL_MEM_READ_ONLY | CL_MEM_ALLOC_HOST_PTR, bytes);
    }
    input.capacity = grown;
  }

  // The sparse kernel in 8^3 blocks reads each beam's reachable rows from the host (beam_rows);
  // elsewhere it finds them itself.
  static bool host_row_bits(const BgkMap& map) {
    return map.params().kernel.type == KernelType::kSparse && map.grid().cells_per_side() == 8;
  }

  // One work-group per job on the compute queue, after `wait` (if given).
  void enqueue_kernel(const BgkMap& map, float sigma0, const cl::Buffer& pool, const cl::Buffer& jobs, const cl::Buffer& hits,
                      const cl::Buffer& beams, const cl::Buffer& beam_rows, const cl::Buffer& counts, size_t job_count,
                      const std::vector<cl::Event>* wait, cl::Event* done) {
    const GridParams& grid = map.params().grid;
    const KernelParams& kp = map.params().kernel;
    const float support = kp.support_radius_m(grid.resolution_m);
    const EightCubeKernel eight_cube = host_row_bits(map) ? eight_cube_ : EightCubeKernel::kRuns;
    cl::Kernel& kernel = eight_cube == EightCubeKernel::kWhole   ? whole_kernel_
                         : eight_cube == EightCubeKernel::kPairs ? pairs_kernel_
                         : kp.type == KernelType::kBox           ? box_kernel_
                                                                 : sparse_kernel_;
    const int n = grid.cells_per_side();
    const size_t runs = static_cast<size_t>(n) * n * (n / std::min(n, kCellsPerWorkItem));  // work-items' worth
    // A power of two: a divisor of the block's runs, or (small blocks) a multiple of them.
    const size_t runs_group = std::max(std::min(group_limit_, runs), std::min(kMinGroupSize, group_limit_));
    const size_t group = eight_cube == EightCubeKernel::kWhole   ? 1
                         : eight_cube == EightCubeKernel::kPairs ? kRowPairs
                                                                 : runs_group;
    kernel.setArg(0, pool);
    kernel.setArg(1, jobs);
    kernel.setArg(2, hits);
    kernel.setArg(3, beams);
    kernel.setArg(4, beam_rows);
    kernel.setArg(5, counts);
    kernel.setArg(6, static_cast<cl_int>(grid.cells_per_side()));
    kernel.setArg(7, static_cast<cl_float>(grid.resolution_m));
    kernel.setArg(8, static_cast<cl_float>(kp.inverse_ell_squared()));
    kernel.setArg(9, static_cast<cl_float>(sigma0));
    kernel.setArg(10, static_cast<cl_float>(support * support));
    kernel.setArg(11, static_cast<cl_int>(host_row_bits(map)));
    kernel.setArg(12, static_cast<cl_int>(map.params().preprocess.planar ? map.layer_local_z() : -1));
    compute_.enqueueNDRangeKernel(kernel, cl::NullRange, cl::NDRange(job_count * group), cl::NDRange(group), wait,
                                  done);
  }

  // Adds the pair counts of the set's last launch, waiting for them if needed.
  void collect_stats(LaunchBuffers& set, IntegrateStats& stats) {
    if (set.pending_jobs == 0) return;
    try {
      set.counts_copied.wait();
    } catch (const cl::Error& e) {
      throw device_lost("running a queued scan", e);
    }
    for (size_t j = 0; j < set.pending_jobs; ++j) {
      stats.pairs_evaluated += set.counts_host[2 * j];
      stats.pairs_within_support += set.counts_host[2 * j + 1];
    }
    try {
      const cl_ulong start_ns = set.kernel_done.getProfilingInfo<CL_PROFILING_COMMAND_START>();
      const cl_ulong end_ns = set.kernel_done.getProfilingInfo<CL_PROFILING_COMMAND_END>();
      if (end_ns > start_ns) stats.device_kernel_s += 1e-9 * static_cast<double>(end_ns - start_ns);
    } catch (const cl::Error&) {
      // A driver without timestamps: the report's device_kernel_s stays short, nothing else.
    }
    set.pending_jobs = 0;
  }

  void wait_for_device(const char* doing) {
    try {
      compute_.finish();
      transfer_.finish();
    } catch (const cl::Error& e) {
      throw device_lost(doing, e);
    }
  }

  // Another map (one integrator serves one map at a time; see host_changed()).
  void adopt(const BgkMap& map) {
    if (&map != map_ || map.block_count() < pool_.slots()) {
      map_ = &map;
      take_host_cells_ = true;
    }
  }

  // The device takes what the host changed: every cell (host_changed of all, another map) or the
  // slots host_changed named; slots the host added since start at the prior, as there.
  void take_host_changes(const BgkMap& map) {
    pool_.mirror(compute_, map, take_host_cells_);
    if (!take_host_cells_ && !host_slots_.empty()) {
      std::sort(host_slots_.begin(), host_slots_.end());
      host_slots_.erase(std::unique(host_slots_.begin(), host_slots_.end()), host_slots_.end());
      pool_.write_slots(compute_, map, host_slots_, scatter_kernel_);
    }
    take_host_cells_ = false;
    host_slots_.clear();
  }

  // Work that already ran on the device cannot be told apart from work that did not when the
  // device fails while running it: the build stops rather than produce a different map.
  std::runtime_error device_lost(const char* doing, const cl::Error& e) const {
    return std::runtime_error("the OpenCL device '" + program_->info.full_name() + "' failed while " + doing + " (" +
                              e.what() + ": " + cl_error_name(e.err()) +
                              "); the map on it is lost. Rerun with --backend cpu");
  }

  // The device refused this scan's work before running it: take the map back to the host (the
  // launches queued so far included) and carry on with the CPU path.
  void fall_back(BgkMap& map, IntegrateStats& stats, const std::string& reason) {
    wait_for_device("taking the map back after a refusal");
    for (LaunchBuffers& set : sets_) collect_stats(set, stats);
    if (!take_host_cells_) {
      // The slots the host changed since the device last took them are newer on the host.
      const size_t cells = static_cast<size_t>(map.cells_per_block());
      std::vector<Cell> newer;
      for (const uint32_t slot : host_slots_) newer.insert(newer.end(), map.block_cells(slot), map.block_cells(slot) + cells);
      try {
        pool_.read_back(compute_, map);
      } catch (const cl::Error& e) {
        throw device_lost("taking the map back after a refusal", e);
      }
      for (size_t i = 0; i < host_slots_.size(); ++i)
        std::copy(newer.begin() + i * cells, newer.begin() + (i + 1) * cells, map.block_cells(host_slots_[i]));
    }
    host_slots_.clear();
    host_current_ = true;
    switch_to_cpu("could not take scan " + std::to_string(scans_) + ": " + reason +
                  "; that scan's remaining blocks and every later scan ran on the CPU path (the same map)");
  }

  // From now on the CPU path does the work; says so once.
  void switch_to_cpu(const std::string& what) {
    cpu_ = std::make_unique<CpuIntegrator>(cpu_threads_);
    note_ = "OpenCL device '" + program_->info.full_name() + "' " + what;
    log_warning(note_);
  }

  // The blocks (and parts of blocks) of the scan that were not launched yet, as CPU work.
  ScanBuckets remaining_work(const ScanBuckets& buckets, size_t pieces_launched) const {
    ScanBuckets rest;
    rest.hits = buckets.hits;
    rest.beams = buckets.beams;
    for (size_t i = pieces_launched; i < pieces_.size(); ++i) {
      const WorkPiece& p = pieces_[i];
      BlockWork w = buckets.blocks[p.block];
      w.hit_begin += p.hit_offset;
      w.hit_count = p.hit_count;
      w.beam_begin += p.beam_offset;
      w.beam_count = p.beam_count;
      rest.blocks.push_back(w);
    }
    return rest;
  }

  std::shared_ptr<const DeviceProgram> program_;
  int cpu_threads_;
  int host_threads_;
  bool staged_;                // launch inputs staged in pinned memory and copied (else mapped)
  cl::CommandQueue compute_;   // pool updates, kernels, read-backs: in order
  cl::CommandQueue transfer_;  // filling launch inputs while the compute queue runs
  cl::Kernel sparse_kernel_, box_kernel_, pairs_kernel_, whole_kernel_;
  cl::Kernel gather_kernel_, scatter_kernel_;  // the host's reads and writes of some slots
  cl::Kernel decay_kernel_;                     // forgetting's decay of some slots
  EightCubeKernel eight_cube_ = EightCubeKernel::kRuns;  // for 8^3 blocks with the sparse kernel
  DeviceCellPool pool_;
  LaunchLimits limits_;
  size_t group_limit_ = 1;
  std::array<LaunchBuffers, 2> sets_;
  size_t next_set_ = 0;
  std::vector<WorkPiece> pieces_;
  std::vector<Launch> launches_;

  const BgkMap* map_ = nullptr;  // the map the device mirrors
  bool take_host_cells_ = true;  // the host's cells are newer than the device's
  std::vector<uint32_t> host_slots_;  // else these slots' (host_changed)
  bool host_current_ = true;     // the device's cells are not newer than the host's
  uint64_t scans_ = 0;
  std::unique_ptr<CpuIntegrator> cpu_;  // set once the device could not go on
  std::string note_;
};

}  // namespace
}  // namespace opencl_detail

std::unique_ptr<Integrator> make_opencl_integrator(const OpenClOptions& options, int cpu_fallback_threads) {
  std::shared_ptr<const opencl_detail::DeviceProgram> program = opencl_detail::device_program(options);
  const std::string device = program->info.full_name();
  try {
    return std::make_unique<opencl_detail::OpenClIntegrator>(std::move(program), options, cpu_fallback_threads);
  } catch (const cl::Error& e) {
    throw OpenClUnavailable("cannot set up the OpenCL device '" + device + "': " + e.what() + " " +
                            opencl_detail::cl_error_name(e.err()));
  }
}

}  // namespace bgkmap
