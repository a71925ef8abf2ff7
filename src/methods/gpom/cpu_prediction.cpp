#include <omp.h>

#include "core/parallel_errors.hpp"
#include "core/progress_counter.hpp"
#include "methods/gpom/calibration.hpp"
#include "methods/gpom/prediction.hpp"

namespace bgkmap::gpom {

void evaluate_on_cpu(const Evaluation& e, std::vector<std::vector<LooSample>>& loo, uint64_t& pairs) {
  uint64_t evaluated_pairs = 0;
  ParallelErrors errors;
  ProgressCounter counter(e.progress, e.phase, "blocks", e.dirty.size());
#pragma omp parallel for schedule(dynamic) num_threads(e.threads) reduction(+ : evaluated_pairs)
  for (int64_t b = 0; b < static_cast<int64_t>(e.dirty.size()); ++b)
    errors.run([&] {
      Scratch s;
      std::vector<GpPrediction> latent;
      GpomCell* cells = e.cells.block(e.dirty[b]);
      int evaluated = 0;
      e.queries.for_each_query(e.cells.key_of_slot(e.dirty[b]), 1, [&](int local, const Vec3d& q) {
        if (!e.models.of_query(q, s)) {
          cells[local] = e.solver.unreached(q);
          return;
        }
        if (evaluated++ % kLooEvery == 0) e.solver.sample_leave_one_out(s, loo[b]);
        latent.clear();
        for (size_t h = 0; h < s.models.size(); ++h) {
          latent.push_back(e.solver.latent(s, h, q));
          evaluated_pairs += s.models[h].train.size();
        }
        cells[local] = e.solver.cell_of(latent, s);
      });
      counter.add();
    });
  errors.rethrow();
  counter.finish();
  pairs += evaluated_pairs;
}

}  // namespace bgkmap::gpom
