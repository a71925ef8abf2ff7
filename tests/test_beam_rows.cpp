// The rows of an 8^3 block a beam can reach (src/integrate/beam_rows_8.hpp): both back ends skip
// the rows without a bit, so the bits must hold every cell the kernel gives a non-zero value,
// checked cell by cell against the back ends' own float expressions on random beams.
#include <gtest/gtest.h>

#include <cmath>
#include <ostream>
#include <random>
#include <vector>

#include "core/bgk_math.h"
#include "bgkmap/core/params.hpp"
#include "integrate/beam_rows_8.hpp"
#include "integrate/local_frames.hpp"

namespace bgkmap {
namespace {

struct Setting {
  float res, ell;
};
// gtest names the failing case by it (else a dump of its bytes).
void PrintTo(const Setting& s, std::ostream* out) { *out << "res " << s.res << " m, ell " << s.ell << " m"; }

// Random beams in the frame of block (0, 0, 0) (cells at (x, y, z) * res), as bucketing makes them:
// origins and ends anywhere within a few block sizes, some ending inside or near the block.
std::vector<LocalBeam> random_beams(const Setting& s, uint32_t seed, int count) {
  std::mt19937 rng(seed);
  const double size = 8 * s.res;
  std::uniform_real_distribution<double> around(-2 * size, 3 * size), near(-s.ell, size + s.ell);
  const Vec3d c0{0, 0, 0}, mid{3.5 * s.res, 3.5 * s.res, 3.5 * s.res};
  std::vector<LocalBeam> beams;
  for (int i = 0; i < count; ++i) {
    const Vec3f origin{float(around(rng)), float(around(rng)), float(around(rng))};
    // Every third beam ends near the block; the others pass by or through it.
    const Vec3f end = i % 3 == 0 ? Vec3f{float(near(rng)), float(near(rng)), float(near(rng))}
                                 : Vec3f{float(around(rng)), float(around(rng)), float(around(rng))};
    beams.push_back(make_local_beam(c0, mid, origin, end));
  }
  // Along the axes, where the interval formulas divide by (almost) nothing.
  for (int axis = 0; axis < 3; ++axis) {
    Vec3f a{float(2.5 * s.res), float(4.2 * s.res), float(3.1 * s.res)}, b = a;
    (axis == 0 ? a.x : axis == 1 ? a.y : a.z) = float(-3 * size);
    (axis == 0 ? b.x : axis == 1 ? b.y : b.z) = float(4 * size);
    beams.push_back(make_local_beam(c0, mid, a, b));
  }
  return beams;
}

class BeamRows : public testing::TestWithParam<Setting> {};

TEST_P(BeamRows, HoldEveryCellTheKernelReaches) {
  const Setting s = GetParam();
  const RowReach8 g = RowReach8::make(s.res, s.ell);
  KernelParams kernel;
  kernel.ell_m = s.ell;
  const float inv_ell2 = kernel.inverse_ell_squared();  // what the back ends use
  size_t cells_reached = 0, rows_reached = 0, rows_flagged = 0;
  const std::vector<LocalBeam> beams = random_beams(s, 7, 3000);
  std::vector<uint64_t> masks(beams.size());
  beam_row_masks_8(g, beams.data(), beams.size(), masks.data());
  for (size_t k = 0; k < beams.size(); ++k) {
    const LocalBeam& b = beams[k];
    const uint64_t mask = masks[k];
    ASSERT_EQ(mask, beam_row_mask_8(g, b)) << "beam " << k;
    for (int row = 0; row < kRows8; ++row) {
      bool reached = false;
      for (int x = 0; x < 8; ++x) {
        const float d2 = bgk_anchored_segment_dist2(x * s.res, (row & 7) * s.res, (row >> 3) * s.res, b.qx, b.qy, b.qz,
                                                    b.ux, b.uy, b.uz, b.s_min, b.s_max);
        if (bgk_sparse_kernel_d2(d2, inv_ell2, kernel.sigma0) == 0.0f) continue;
        reached = true;
        ++cells_reached;
      }
      if (reached) {
        ++rows_reached;
        ASSERT_TRUE((mask >> row) & 1u) << "row " << row << " of beam " << k << " reached but not flagged";
      }
      rows_flagged += (mask >> row) & 1u;
    }
  }
  // Not vacuous, and not every row: the bits cull.
  EXPECT_GT(cells_reached, 1000u);
  EXPECT_LT(rows_flagged, 2 * rows_reached);
}

INSTANTIATE_TEST_SUITE_P(Settings, BeamRows,
                         testing::Values(Setting{0.1f, 0.2f},    // la3dm's sim settings: reach 2 cells
                                         Setting{0.2f, 0.6f},    // the campus preset: 3 cells
                                         Setting{0.05f, 0.3f},   // reach wider than the block
                                         Setting{0.1f, 0.05f}));  // reach under a cell

#if BGK_AVX512_BEAMS
BGK_TARGET_AVX512 uint64_t row_mask_avx512(const RowReach8& g, const LocalBeam& b) {
  return beam_row_mask_8_avx512(g, b);
}

// The AVX-512 row bits (the CPU back end's and the OpenCL staging's where the CPU has AVX-512)
// are the portable ones, bit for bit.
TEST_P(BeamRows, Avx512BitsAreThePortableBits) {
  if (!cpu_runs_avx512_beams()) GTEST_SKIP() << "this CPU has no AVX-512 (x86-64-v4)";
  const Setting s = GetParam();
  const RowReach8 g = RowReach8::make(s.res, s.ell);
  size_t rows = 0;
  for (const LocalBeam& b : random_beams(s, 11, 3000)) {
    const uint64_t expected = beam_row_mask_8(g, b);
    ASSERT_EQ(row_mask_avx512(g, b), expected);
    rows += static_cast<size_t>(__builtin_popcountll(expected));
  }
  EXPECT_GT(rows, 3000u);  // the beams reach rows
}
#endif

TEST(BeamRowMask, KnownRows) {
  const Setting s{0.1f, 0.2f};  // reach: two cells
  const RowReach8 g = RowReach8::make(s.res, s.ell);
  const Vec3d c0{0, 0, 0}, mid{0.35, 0.35, 0.35};
  auto mask_of = [&](Vec3f a, Vec3f b) { return beam_row_mask_8(g, make_local_beam(c0, mid, a, b)); };
  auto rows_where = [](auto keep) {
    uint64_t m = 0;
    for (int row = 0; row < kRows8; ++row)
      if (keep(row & 7, row >> 3)) m |= uint64_t{1} << row;
    return m;
  };
  // Along x through row (y 3, z 4): the rows within two cells of it in y-z (13 of them).
  const uint64_t along_x = mask_of({-5, 0.3f, 0.4f}, {5, 0.3f, 0.4f});
  EXPECT_EQ(along_x, rows_where([](int y, int z) { return (y - 3) * (y - 3) + (z - 4) * (z - 4) <= 4; }));
  EXPECT_EQ(__builtin_popcountll(along_x), 13);
  // Along z through x 3, y 3: every z layer, rows within two cells in y.
  EXPECT_EQ(mask_of({0.3f, 0.3f, -5}, {0.3f, 0.3f, 5}), rows_where([](int y, int) { return std::abs(y - 3) <= 2; }));
  // Ending three cells before the block in x, or passing three cells above it: nothing.
  EXPECT_EQ(mask_of({-5, 0.3f, 0.4f}, {-0.3f, 0.3f, 0.4f}), 0u);
  EXPECT_EQ(mask_of({-5, 0.3f, 1.0f}, {5, 0.3f, 1.0f}), 0u);
  // Ending two cells before the block in x (within reach of column 0 only): the same rows.
  EXPECT_EQ(mask_of({-5, 0.3f, 0.4f}, {-0.19f, 0.3f, 0.4f}), along_x);
}

}  // namespace
}  // namespace bgkmap
