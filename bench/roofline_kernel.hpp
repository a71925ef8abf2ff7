// This machine's pair-evaluation roofline: how many (cell, observation) pairs per second the CPU
// back end's per-pair math can reach when nothing but that math is done.
//
// What it IS: the same per-pair expressions as src/integrate/cpu/cpu_integrator.cpp (hits:
// squared distance from the cell to the point, beams: bgk_anchored_segment_dist2 to the free
// segment; then bgk_sparse_kernel_d2, the add into the cell's accumulator and the within-l
// count), on the same data structures (LocalHit, LocalBeam), compiled with the library's flags
// and the same function multiversioning (src/integrate/cpu/cpu_clones.hpp), in the layout that
// is ideal for it: every observation against a tile of 16 x 8 x 8 cells held in L1, one
// contiguous 16-lane loop per row of 16 cells (so a hit's y-z distance is computed once per
// row, as a contiguous row allows), and every pair within l (the tile is a few hundredths of l
// across and the observations lie within l / 2 of it), so no work is wasted. Hits and beams are
// measured separately: a beam pair (segment distance) costs more than a hit pair. Where the CPU
// has AVX-512, beams go through the back end's own loop for 8^3 blocks (listed items, software
// pipelined: beams_8_avx512.hpp) on a block whose every row pair is within l, since that loop is
// faster than the plain row loop (its per-beam listing of items is included): the roofline is
// the best this code does, not a plain loop.
//
// What it is NOT: a bound on the whole insert (no preprocessing, bucketing, block allocation or
// map update), nor a hardware peak (FLOP/s or bandwidth): it is the best this code's per-pair
// math does here. The back end's real blocks pay for culling (which cells to evaluate), packing
// short runs of cells into 16-lane loops and scattering the results, per-block accumulators and
// cache misses; the roofline pays for none of them. The OpenCL back end is compared with it too
// (PoCL runs on the same cores), but PoCL compiles the kernel its own way. A different kernel
// formula (e.g. a cheaper sin/cos) moves the roofline with it: rerun it after changing
// src/core/bgk_math.h.
#pragma once

#include <cstdint>
#include <memory>

namespace bgkmap::bench {

enum class PairKind { kHit, kBeam };
const char* to_string(PairKind kind);

// Whether beam pairs go through the CPU back end's AVX-512 loop (src/integrate/cpu/
// beams_8_avx512.hpp), as the back end's do on this CPU; otherwise the portable row loop.
bool beams_avx512();

struct RooflinePass {
  uint64_t pairs = 0;   // pairs evaluated, summed over the threads
  uint64_t within = 0;  // of those, closer than l (all of them, by construction)
};

// A fixed set of observations (the same on every thread) and one tile of cells per thread.
class Roofline {
 public:
  Roofline(PairKind kind, int threads);
  ~Roofline();
  Roofline(const Roofline&) = delete;
  Roofline& operator=(const Roofline&) = delete;

  // Every thread evaluates every observation against its own tile (OpenMP, `threads` threads).
  RooflinePass pass();
  int threads() const { return threads_; }

 private:
  struct Data;
  PairKind kind_;
  int threads_;
  std::unique_ptr<Data> data_;
};

struct RooflineMeasurement {
  double pairs_per_s = 0;
  double cores_used = 0;  // process CPU seconds per wall second while measuring (bench_support.hpp)
};

// Pairs per second of `kind` with `threads` threads: the median of `samples` timings of at least
// `min_seconds` each (after one untimed pass that warms the caches and the threads).
RooflineMeasurement measure_roofline(PairKind kind, int threads, int samples = 5, double min_seconds = 0.1);

// The CPU clone the loader picks here ("avx512f", "avx2" or "default"), for the report.
const char* cpu_clone_in_use();

}  // namespace bgkmap::bench
