// gpom's prediction: every cell of the dirty blocks from its local models, on the CPU (Eigen, in
// parallel over blocks) or with the local models solved in batches on a device.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "bgkmap/core/progress.hpp"
#include "integrate/local_gp_batch.hpp"
#include "map/block_store.hpp"
#include "methods/gpom/cell_solver.hpp"

namespace bgkmap::gpom {

// One evaluation of the dirty blocks (read-only but for the cells).
struct Evaluation {
  const CellQueries& queries;
  const LocalModels& models;
  const CellSolver& solver;
  BlockStore<GpomCell>& cells;
  const std::vector<uint32_t>& dirty;  // slots of cells, in key order
  int threads;
  const ProgressCallback& progress;
  std::string phase;  // the progress phase's name
};

// Every cell of the dirty blocks; per dirty block its leave-one-out samples in loo, the pairs
// (training input, query) evaluated added to `pairs`.
void evaluate_on_cpu(const Evaluation& e, std::vector<std::vector<LooSample>>& loo, uint64_t& pairs);

// As evaluate_on_cpu, the local models solved on `device` (plain kernels of the distance only).
// False when the device fails (its info().note says why): then nothing is to be trusted of loo,
// pairs and the cells, and the caller evaluates on the CPU.
bool evaluate_on_device(const Evaluation& e, LocalGpDevice& device, const GpHyperParams& hp, size_t neighbours,
                        std::vector<std::vector<LooSample>>& loo, uint64_t& pairs);

}  // namespace bgkmap::gpom
