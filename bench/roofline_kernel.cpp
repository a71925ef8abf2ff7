// The pair-evaluation roofline (see roofline_kernel.hpp for what it is and is not). Compiled with
// the library's compile options and clone attributes (bench/CMakeLists.txt), so that the loops
// below get the same code generation as the CPU back end's.
#include "roofline_kernel.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "bench_support.hpp"
#include "bgkmap/core/bgk_math.h"
#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/cpu/cpu_clones.hpp"

namespace bgkmap::bench {

namespace {

constexpr int kLanes = 16;   // cells per row: one 16-lane loop (a full AVX-512 register)
constexpr int kRows = 64;    // 8 x 8 rows (y fastest, then z)
constexpr int kCells = kLanes * kRows;
constexpr int kObservations = 4096;  // per thread and pass: 4 M pairs, tens of milliseconds

struct TileGeometry {
  float res, ell2, inv_ell2, sigma0;
};

// One thread's accumulators; 4 KiB, so they stay in L1 for the whole pass.
struct alignas(64) Tile {
  float cells[kCells] = {};
};

// Cell (i, r) sits at (i, r & 7, r >> 3) * res. With res = l / 64 the tile spans 15 x 7 x 7
// res, under 0.14 l from its centre: every observation within l / 2 of the centre is within l of
// every cell.
TileGeometry tile_geometry() {
  const float ell = 0.2f;
  TileGeometry g;
  g.res = ell / 64;
  g.ell2 = ell * ell;
  g.inv_ell2 = 1.0f / (ell * ell);
  g.sigma0 = 0.1f;
  return g;
}

// The per-pair expressions of cpu_integrator.cpp's hit_row / beam_row, over 16 contiguous cells.
BGK_INLINE_INTO_CLONES uint32_t hit_row16(const TileGeometry& g, float* row, float px, float dyz2) {
  uint32_t near = 0;
#pragma omp simd reduction(+ : near)
  for (int i = 0; i < kLanes; ++i) {
    const float dx = i * g.res - px;
    const float d2 = dx * dx + dyz2;
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near += d2 < g.ell2;
  }
  return near;
}

BGK_INLINE_INTO_CLONES uint32_t beam_row16(const TileGeometry& g, float* row, float cy, float cz, const LocalBeam& b) {
  uint32_t near = 0;
#pragma omp simd reduction(+ : near)
  for (int i = 0; i < kLanes; ++i) {
    const float d2 = bgk_anchored_segment_dist2(i * g.res, cy, cz, b.qx, b.qy, b.qz, b.ux, b.uy, b.uz, b.s_min, b.s_max);
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near += d2 < g.ell2;
  }
  return near;
}

BGK_CPU_CLONES uint64_t evaluate_hits(const TileGeometry& g, const LocalHit* hits, size_t count, float* cells) {
  uint64_t within = 0;
  for (size_t h = 0; h < count; ++h) {
    const LocalHit p = hits[h];
    for (int r = 0; r < kRows; ++r) {
      const float dy = (r & 7) * g.res - p.y, dz = (r >> 3) * g.res - p.z;
      within += hit_row16(g, cells + r * kLanes, p.x, dy * dy + dz * dz);
    }
  }
  return within;
}

BGK_CPU_CLONES uint64_t evaluate_beams(const TileGeometry& g, const LocalBeam* beams, size_t count, float* cells) {
  uint64_t within = 0;
  for (size_t k = 0; k < count; ++k) {
    const LocalBeam b = beams[k];
    for (int r = 0; r < kRows; ++r) within += beam_row16(g, cells + r * kLanes, (r & 7) * g.res, (r >> 3) * g.res, b);
  }
  return within;
}

// A point uniformly in the ball of radius `radius` around c.
template <class Rng>
void point_in_ball(Rng& rng, const float c[3], float radius, float out[3]) {
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  float v[3];
  do {
    for (float& x : v) x = unit(rng);
  } while (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] > 1.0f);
  for (int i = 0; i < 3; ++i) out[i] = c[i] + radius * v[i];
}

}  // namespace

const char* to_string(PairKind kind) { return kind == PairKind::kHit ? "hit" : "beam"; }

struct Roofline::Data {
  TileGeometry geometry = tile_geometry();
  std::vector<LocalHit> hits;
  std::vector<LocalBeam> beams;
  std::vector<Tile> tiles;  // one per thread
};

Roofline::Roofline(PairKind kind, int threads) : kind_(kind), threads_(threads), data_(std::make_unique<Data>()) {
  if (threads < 1) throw std::invalid_argument("roofline: threads must be >= 1");
  Data& d = *data_;
  d.tiles.resize(static_cast<size_t>(threads));
  const float r = d.geometry.res;
  const float centre[3] = {7.5f * r, 3.5f * r, 3.5f * r};
  const float ell = std::sqrt(d.geometry.ell2);
  std::mt19937 rng(20261122);
  std::uniform_real_distribution<float> extent(0.0f, 2.0f);
  for (int i = 0; i < kObservations; ++i) {
    float p[3];
    point_in_ball(rng, centre, 0.5f * ell, p);
    if (kind == PairKind::kHit) {
      d.hits.push_back({p[0], p[1], p[2]});
      continue;
    }
    // A free segment through p (its anchor) in a random direction, p inside [s_min, s_max]: the
    // distance from any cell is at most its distance to p, so within l.
    float u[3];
    const float origin[3] = {0, 0, 0};
    do point_in_ball(rng, origin, 1.0f, u);
    while (u[0] * u[0] + u[1] * u[1] + u[2] * u[2] < 1e-2f);
    const float n = std::sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]);
    d.beams.push_back({p[0], p[1], p[2], u[0] / n, u[1] / n, u[2] / n, -extent(rng), extent(rng)});
  }
}

Roofline::~Roofline() = default;

RooflinePass Roofline::pass() {
  Data& d = *data_;
  uint64_t within = 0;
#pragma omp parallel num_threads(threads_) reduction(+ : within)
  {
    float* cells = d.tiles[static_cast<size_t>(omp_get_thread_num())].cells;
    within += kind_ == PairKind::kHit ? evaluate_hits(d.geometry, d.hits.data(), d.hits.size(), cells)
                                      : evaluate_beams(d.geometry, d.beams.data(), d.beams.size(), cells);
  }
  RooflinePass out;
  out.pairs = static_cast<uint64_t>(threads_) * kObservations * kCells;
  out.within = within;
  return out;
}

RooflineMeasurement measure_roofline(PairKind kind, int threads, int samples, double min_seconds) {
  Roofline roofline(kind, threads);
  roofline.pass();
  std::vector<double> rates;
  const CoresUsed usage;
  for (int s = 0; s < samples; ++s) {
    const CoresUsed sample;
    uint64_t pairs = 0;
    do pairs += roofline.pass().pairs;
    while (sample.wall_seconds() < min_seconds);
    rates.push_back(static_cast<double>(pairs) / sample.wall_seconds());
  }
  std::nth_element(rates.begin(), rates.begin() + rates.size() / 2, rates.end());
  return {rates[rates.size() / 2], usage.cores()};
}

const char* cpu_clone_in_use() {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
  if (__builtin_cpu_supports("avx512f")) return "avx512f";
  if (__builtin_cpu_supports("avx2")) return "avx2";
#endif
  return "default";
}

}  // namespace bgkmap::bench
