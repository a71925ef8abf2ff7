#include <omp.h>

#include <algorithm>
#include <cmath>

#include "core/parallel_errors.hpp"
#include "core/progress_counter.hpp"
#include "methods/gpom/calibration.hpp"
#include "methods/gpom/prediction.hpp"

namespace bgkmap::gpom {

namespace {

constexpr size_t kBlocksPerBatch = 64;

// Blocks [first, last) of the dirty ones: per block its batch of models (gathered in parallel over
// blocks) and, per cell, its first model (-1: unknown).
void gather_models(const Evaluation& e, size_t first, size_t last, int max_n, std::vector<LocalGpBatch>& batches,
                   std::vector<std::vector<int32_t>>& first_model, std::vector<std::vector<LooSample>>& loo) {
  const int cells_per_block = e.queries.cells_per_block();
  ParallelErrors errors;
#pragma omp parallel for schedule(dynamic) num_threads(e.threads)
  for (int64_t b = static_cast<int64_t>(first); b < static_cast<int64_t>(last); ++b)
    errors.run([&] {
      Scratch s;
      LocalGpBatch& batch = batches[b - first];
      batch.max_n = max_n;
      std::vector<int32_t>& model_of = first_model[b - first];
      model_of.assign(static_cast<size_t>(cells_per_block), -1);
      int evaluated = 0;
      e.queries.for_each_query(e.cells.key_of_slot(e.dirty[b]), 1, [&](int local, const Vec3d& q) {
        if (!e.models.of_query(q, s)) return;
        if (evaluated++ % kLooEvery == 0) e.solver.sample_leave_one_out(s, loo[b]);
        model_of[local] = static_cast<int32_t>(batch.size());
        for (const LocalModel& model : s.models) batch.add(model.train, e.solver.warp().modelled(model.labels, s.warped), q);
      });
    });
  errors.rethrow();
}

// The cells of blocks [first, last) from the device's solutions of `all` (the blocks' batches end to end).
void store_cells(const Evaluation& e, size_t first, size_t last, const std::vector<LocalGpBatch>& batches,
                 const std::vector<std::vector<int32_t>>& first_model, const LocalGpBatch& all,
                 const std::vector<double>& mean, const std::vector<double>& variance, uint64_t& pairs) {
  const size_t hypotheses = e.models.hypotheses();
  size_t offset = 0;
  for (size_t b = first; b < last; ++b) {
    Scratch s;
    std::vector<GpPrediction> latent(hypotheses);
    GpomCell* cells = e.cells.block(e.dirty[b]);
    const std::vector<int32_t>& model_of = first_model[b - first];
    for (size_t local = 0; local < model_of.size(); ++local) {
      if (model_of[local] < 0) {
        cells[local] = GpomCell{};
        continue;
      }
      for (size_t h = 0; h < hypotheses; ++h) {
        const size_t m = offset + static_cast<size_t>(model_of[local]) + h;
        if (!std::isfinite(mean[m])) throw GpNotPositiveDefinite();
        latent[h].mean = mean[m];
        latent[h].variance = variance[m];
        pairs += static_cast<uint64_t>(all.count[m]);
      }
      cells[local] = e.solver.cell_of(latent, s);
    }
    offset += batches[b - first].size();
  }
}

}  // namespace

// Chunks of dirty blocks whose local models are gathered on the host, solved in one batch, and
// stored as the CPU path stores them.
bool evaluate_on_device(const Evaluation& e, LocalGpDevice& device, const GpHyperParams& hp, size_t neighbours,
                        std::vector<std::vector<LooSample>>& loo, uint64_t& pairs) {
  const int max_n = static_cast<int>(2 * neighbours);
  const LocalGpCovariance covariance{static_cast<int>(hp.covariance), hp.ell_m, hp.signal_var,
                                     hp.noise_std * hp.noise_std};
  ProgressCounter counter(e.progress, e.phase, "blocks", e.dirty.size());
  for (size_t first = 0; first < e.dirty.size(); first += kBlocksPerBatch) {
    const size_t last = std::min(e.dirty.size(), first + kBlocksPerBatch);
    std::vector<LocalGpBatch> batches(last - first);
    std::vector<std::vector<int32_t>> first_model(last - first);
    gather_models(e, first, last, max_n, batches, first_model, loo);
    LocalGpBatch all;
    all.max_n = max_n;
    for (const LocalGpBatch& batch : batches) all.append(batch);
    std::vector<double> mean(all.size()), variance(all.size());
    if (!device.predict(all, covariance, mean.data(), variance.data())) return false;
    store_cells(e, first, last, batches, first_model, all, mean, variance, pairs);
    counter.add(last - first);
  }
  counter.finish();
  return true;
}

}  // namespace bgkmap::gpom
