// `mpirun -np K bgkmap build ...`: one BGK-L map built by K processes, each owning the blocks of
// a run of the spatial partition (dist/partition.hpp). Rank r reads scans r, r+K, r+2K, ...,
// prepares them, finds with bucketing's exact reach test which ranks' blocks each observation
// reaches and sends it to those only; every rank maps the scans' observations in global scan
// order onto its own blocks, so every cell's sum is the one a single process computes, bit for
// bit. The ranks write shards (dist/shards.hpp); rank 0 merges them into the outputs. The MPI
// calls are in the bgkmap_mpi library only (src/dist/distributed_build.cpp); this header needs
// no MPI.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/build/build_session.hpp"

namespace bgkmap {

// inputs, outputs (written by rank 0 from the merged shards; may be empty), report (written by
// rank 0), ot_values, params; backend.threads 0: the cores divided among the node's ranks.
struct DistributedBuildRequest : BuildTargets {
  std::string shards;                // shard folder; empty: the first output + ".shards"
  uint64_t checkpoint_every = 0;     // scans between checkpoints of every rank's shard; 0 = none
  std::string resume;                // a shard folder (or its manifest) to continue from
  bool quiet = false;
  // Install handlers so that a rank ended by a signal it can catch (SIGTERM, SIGINT, SIGSEGV, SIGBUS,
  // SIGFPE, SIGABRT) prints its rank and what it was doing: process-wide, for the program to choose.
  bool report_fatal_signals = false;
  // Fault injection for the tests, "R:G[:SIGNAL]": rank R sends itself SIGNAL (default SIGKILL, as
  // a lost node) when it is about to map scan G; empty: none (the CLI takes BGKMAP_KILL_RANK_AT).
  std::string kill_rank_at;
};

// True when this process was started by mpirun (Open MPI, or a PMI/PMIx launcher).
bool launched_by_mpirun();

// Runs the build on every rank (MPI_Init to MPI_Finalize). A rank that fails ends the job with
// MPI_Abort after one line naming the rank and the scan.
void run_distributed_build(const DistributedBuildRequest& request);

}  // namespace bgkmap
