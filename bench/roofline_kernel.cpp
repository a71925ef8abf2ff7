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
#include "core/bgk_math.h"
#include "bgkmap/integrate/bucketing.hpp"
#include "integrate/cpu/beams_8_avx512.hpp"
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
// Pairs within l are counted per lane and summed once per pass, as the back end sums once per block.
struct alignas(64) LaneCounts {
  uint32_t lane[kLanes] = {};
  uint64_t total() const {
    uint64_t sum = 0;
    for (uint32_t n : lane) sum += n;
    return sum;
  }
};

// Geometry and beam by value: copies the row's stores cannot alias, so the loops if-convert and
// vectorize.
BGK_INLINE_INTO_CLONES void hit_row16(const TileGeometry g, float* row, float px, float dyz2, LaneCounts& near) {
#pragma omp simd
  for (int i = 0; i < kLanes; ++i) {
    const float dx = i * g.res - px;
    const float d2 = dx * dx + dyz2;
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near.lane[i] += d2 < g.ell2;
  }
}

BGK_INLINE_INTO_CLONES void beam_row16(const TileGeometry g, float* row, float cy, float cz, const LocalBeam s,
                                       LaneCounts& near) {
#pragma omp simd
  for (int i = 0; i < kLanes; ++i) {
    const float d2 = bgk_anchored_segment_dist2(i * g.res, cy, cz, s.qx, s.qy, s.qz, s.ux, s.uy, s.uz, s.s_min, s.s_max);
    row[i] += bgk_sparse_kernel_d2(d2, g.inv_ell2, g.sigma0);
    near.lane[i] += d2 < g.ell2;
  }
}

BGK_CPU_CLONES uint64_t evaluate_hits(const TileGeometry& g, const LocalHit* hits, size_t count, float* cells) {
  LaneCounts near;
  for (size_t h = 0; h < count; ++h) {
    const LocalHit p = hits[h];
    for (int r = 0; r < kRows; ++r) {
      const float dy = (r & 7) * g.res - p.y, dz = (r >> 3) * g.res - p.z;
      hit_row16(g, cells + r * kLanes, p.x, dy * dy + dz * dz, near);
    }
  }
  return near.total();
}

BGK_CPU_CLONES uint64_t evaluate_beams(const TileGeometry& g, const LocalBeam* beams, size_t count, float* cells) {
  LaneCounts near;
  for (size_t k = 0; k < count; ++k) {
    const LocalBeam b = beams[k];
    for (int r = 0; r < kRows; ++r) beam_row16(g, cells + r * kLanes, (r & 7) * g.res, (r >> 3) * g.res, b, near);
  }
  return near.total();
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

bool beams_avx512() {
#if BGK_AVX512_BEAMS
  return cpu_runs_avx512_beams();
#else
  return false;
#endif
}

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
  uint64_t pairs = 0, within = 0;
#pragma omp parallel num_threads(threads_) reduction(+ : pairs, within)
  {
    float* cells = d.tiles[static_cast<size_t>(omp_get_thread_num())].cells;
    if (kind_ == PairKind::kHit) {
      within += evaluate_hits(d.geometry, d.hits.data(), d.hits.size(), cells);
      pairs += static_cast<uint64_t>(kObservations) * kCells;
    } else if (beams_avx512()) {
#if BGK_AVX512_BEAMS
      // The back end's own AVX-512 loop (it runs it on such CPUs) on the tile's first 512 cells
      // as an 8^3 block: every row pair of every beam is within l and evaluated.
      const TileGeometry& g = d.geometry;
      const Beams8Params params{RowReach8::make(g.res, std::sqrt(g.ell2)), g.res, g.ell2, g.inv_ell2, g.sigma0};
      LaneCounts near;
      pairs += add_beams_8_avx512(params, d.beams.data(), static_cast<uint32_t>(d.beams.size()), cells, near.lane);
      within += near.total();
#endif
    } else {
      within += evaluate_beams(d.geometry, d.beams.data(), d.beams.size(), cells);
      pairs += static_cast<uint64_t>(kObservations) * kCells;
    }
  }
  RooflinePass out;
  out.pairs = pairs;
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
  if (__builtin_cpu_supports("x86-64-v4")) return "x86-64-v4 (AVX-512)";
  if (__builtin_cpu_supports("x86-64-v3")) return "x86-64-v3 (AVX2, FMA)";
#endif
  return "default";
}

}  // namespace bgkmap::bench
