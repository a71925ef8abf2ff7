#include "bgkmap/integrate/cpu_integrator.hpp"

#include <omp.h>

#include <vector>

#include "bgkmap/core/bgk_math.h"

namespace bgkmap {

CpuIntegrator::CpuIntegrator(int threads) : threads_(threads > 0 ? threads : omp_get_max_threads()) {}

BackendInfo CpuIntegrator::info() const {
  BackendInfo b;
  b.name = "cpu";
  b.device = "host CPU (OpenMP)";
  b.threads = threads_;
  return b;
}

namespace {

// One block: every cell against the block's hits (alpha) and beams (beta), in the block's frame
// (cell (lx, ly, lz) at (lx, ly, lz) * resolution, see LocalHit / LocalBeam).
template <int kKernel>
void integrate_block(const BlockWork& work, const ScanBuckets& buckets, const Grid& grid,
                     const KernelParams& kernel, float support2, Cell* cells, IntegrateStats& stats) {
  const int n = grid.cells_per_side();
  const float res = static_cast<float>(grid.resolution());
  const float half = 0.5f * res;
  const LocalHit* hits = buckets.hits.data() + work.hit_begin;
  const LocalBeam* beams = buckets.beams.data() + work.beam_begin;
  uint64_t within = 0;
  int local = 0;
  for (int lz = 0; lz < n; ++lz) {
    for (int ly = 0; ly < n; ++ly) {
      for (int lx = 0; lx < n; ++lx, ++local) {
        const float cx = lx * res, cy = ly * res, cz = lz * res;
        float alpha = 0.0f, beta = 0.0f;
        for (uint32_t h = 0; h < work.hit_count; ++h) {
          const LocalHit& p = hits[h];
          if (kKernel == BGK_KERNEL_BOX) {
            const float k = bgk_box_kernel_point(cx, cy, cz, half, p.x, p.y, p.z);
            alpha += k;
            within += k > 0.0f;
            continue;
          }
          const float dx = cx - p.x, dy = cy - p.y, dz = cz - p.z;
          const float d2 = dx * dx + dy * dy + dz * dz;
          if (d2 >= support2) continue;
          ++within;
          alpha += bgk_sparse_kernel_d2(d2, kernel.ell_m, kernel.sigma0);
        }
        for (uint32_t b = 0; b < work.beam_count; ++b) {
          const LocalBeam& s = beams[b];
          if (kKernel == BGK_KERNEL_BOX) {
            const float k = bgk_box_kernel_segment(
                cx, cy, cz, half, s.qx + s.s_min * s.ux, s.qy + s.s_min * s.uy, s.qz + s.s_min * s.uz,
                s.qx + s.s_max * s.ux, s.qy + s.s_max * s.uy, s.qz + s.s_max * s.uz);
            beta += k;
            within += k > 0.0f;
            continue;
          }
          const float d2 = bgk_anchored_segment_dist2(cx, cy, cz, s.qx, s.qy, s.qz, s.ux, s.uy, s.uz, s.s_min, s.s_max);
          if (d2 >= support2) continue;
          ++within;
          beta += bgk_sparse_kernel_d2(d2, kernel.ell_m, kernel.sigma0);
        }
        cells[local].alpha += alpha;
        cells[local].beta += beta;
      }
    }
  }
  stats.pairs_evaluated += static_cast<uint64_t>(grid.cells_per_block()) * (work.hit_count + work.beam_count);
  stats.pairs_within_support += within;
}

}  // namespace

void CpuIntegrator::integrate(const ScanObservations& obs, const ScanBuckets& buckets, BgkMap& map,
                              IntegrateStats& stats) {
  const Grid& grid = map.grid();
  const KernelParams& kernel = map.params().kernel;
  const float support = kernel.support_radius_m(grid.resolution());
  const float support2 = support * support;
  const int64_t count = static_cast<int64_t>(buckets.blocks.size());
  uint64_t evaluated = 0, within = 0;
#pragma omp parallel num_threads(threads_) reduction(+ : evaluated, within)
  {
    IntegrateStats local;
#pragma omp for schedule(dynamic, 4)
    for (int64_t i = 0; i < count; ++i) {
      const BlockWork& work = buckets.blocks[static_cast<size_t>(i)];
      Cell* cells = map.block_cells(work.slot);
      if (kernel.type == KernelType::kBox)
        integrate_block<BGK_KERNEL_BOX>(work, buckets, grid, kernel, support2, cells, local);
      else
        integrate_block<BGK_KERNEL_SPARSE>(work, buckets, grid, kernel, support2, cells, local);
    }
    evaluated += local.pairs_evaluated;
    within += local.pairs_within_support;
  }
  stats.pairs_evaluated += evaluated;
  stats.pairs_within_support += within;
}

}  // namespace bgkmap
