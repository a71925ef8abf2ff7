// The block Gram engines (integrate/block_gram.hpp): the CPU engine against a dense reference, the
// OpenCL engine (kernels/block_gram.cl; PoCL here) against the CPU engine, and the Bayesian Hilbert
// map's update with either engine. Both engines sum the same double products in the same order,
// so the stated tolerance is exact equality.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <vector>

#include "bgkmap/integrate/opencl_integrator.hpp"
#include "integrate/block_gram.hpp"
#include "methods/bhm/bhm_model.hpp"

namespace bgkmap {
namespace {

// Random rows: blocks of `m` columns, each row a few distinct columns with nonzero values.
BlockGramRows random_rows(int m, int blocks, int max_rows, int max_entries, std::mt19937& rng) {
  BlockGramRows rows;
  rows.m = m;
  std::uniform_int_distribution<int> row_count(0, max_rows), entry_count(1, max_entries), col(0, m - 1);
  std::uniform_real_distribution<double> value(0.001, 1.0);
  for (int b = 0; b < blocks; ++b) {
    const int n = b == 1 ? 0 : row_count(rng);  // block 1 has no rows
    for (int r = 0; r < n; ++r) {
      std::vector<bool> used(m, false);
      const int k = std::min(entry_count(rng), m);
      for (int e = 0; e < k; ++e) {
        int c = col(rng);
        while (used[c]) c = (c + 1) % m;
        used[c] = true;
        rows.column.push_back(c);
        rows.value.push_back(value(rng));
      }
      rows.row_begin.push_back(static_cast<uint32_t>(rows.column.size()));
    }
    rows.block_row_begin.push_back(static_cast<uint32_t>(rows.rows()));
  }
  return rows;
}

void random_weights(const BlockGramRows& rows, std::mt19937& rng, std::vector<double>& weight, std::vector<double>& target) {
  std::uniform_real_distribution<double> w(0.01, 0.25), t(-0.6, 0.6);
  weight.resize(rows.rows());
  target.resize(rows.rows());
  for (size_t r = 0; r < rows.rows(); ++r) {
    weight[r] = w(rng);
    target[r] = t(rng);
  }
}

std::unique_ptr<BlockGramEngine> opencl_engine(std::string& why) {
  try {
    return opencl_detail::make_opencl_block_gram(BackendOptions{"opencl", "", 2});
  } catch (const OpenClUnavailable& e) {
    why = e.what();
    return nullptr;
  }
}

TEST(BlockGram, CpuEngineEqualsTheDenseProducts) {
  std::mt19937 rng(7);
  const BlockGramRows rows = random_rows(16, 5, 40, 6, rng);
  std::vector<double> weight, target;
  random_weights(rows, rng, weight, target);
  const size_t m = 16;
  std::vector<double> gram(5 * m * m, -1.0), rhs(5 * m, -1.0);
  auto cpu = make_cpu_block_gram(2);
  cpu->set_rows(rows);
  cpu->accumulate(0, 5, weight, target, gram.data(), rhs.data());
  for (size_t b = 0; b < 5; ++b) {
    // Dense: G = sum_r w_r phi_r phi_r^T, h = sum_r t_r phi_r, every row as a full vector.
    std::vector<double> g(m * m, 0.0), h(m, 0.0);
    for (uint32_t r = rows.block_row_begin[b]; r < rows.block_row_begin[b + 1]; ++r) {
      std::vector<double> phi(m, 0.0);
      for (uint32_t e = rows.row_begin[r]; e < rows.row_begin[r + 1]; ++e) phi[rows.column[e]] = rows.value[e];
      for (size_t j = 0; j < m; ++j) {
        if (phi[j] == 0) continue;
        h[j] += phi[j] * target[r];
        for (size_t i = 0; i < m; ++i) g[i + j * m] += weight[r] * phi[j] * phi[i];
      }
    }
    for (size_t e = 0; e < m * m; ++e) ASSERT_EQ(gram[b * m * m + e], g[e]) << "block " << b << " entry " << e;
    for (size_t j = 0; j < m; ++j) ASSERT_EQ(rhs[b * m + j], h[j]) << "block " << b << " column " << j;
  }
  // Block 1 has no rows: zero, not left as it was.
  for (size_t e = 0; e < m * m; ++e) EXPECT_EQ(gram[m * m + e], 0.0);
}

TEST(BlockGram, OpenClEngineEqualsTheCpuEngineBitForBit) {
  std::string why;
  std::unique_ptr<BlockGramEngine> device = opencl_engine(why);
  if (!device) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  std::mt19937 rng(11);
  auto cpu = make_cpu_block_gram(2);
  // 8 x 8 blocks (2-D default), 4^3 (3-D), a small and an odd size; more rows than one tile.
  for (const int m : {64, 64, 9, 100}) {
    const int blocks = 13;
    const BlockGramRows rows = random_rows(m, blocks, 150, 25, rng);
    std::vector<double> weight, target;
    random_weights(rows, rng, weight, target);
    cpu->set_rows(rows);
    device->set_rows(rows);
    // All blocks in one call, then a sub-range (as bhm's colours call it).
    for (const auto& [first, last] : {std::pair<uint32_t, uint32_t>{0, blocks}, {4, 9}}) {
      const size_t n = last - first, mm = size_t(m) * m;
      std::vector<double> g_cpu(n * mm), h_cpu(n * m), g_cl(n * mm, -1.0), h_cl(n * m, -1.0);
      cpu->accumulate(first, last, weight, target, g_cpu.data(), h_cpu.data());
      device->accumulate(first, last, weight, target, g_cl.data(), h_cl.data());
      size_t differing = 0;
      for (size_t e = 0; e < n * mm; ++e) differing += g_cpu[e] != g_cl[e];
      for (size_t e = 0; e < n * size_t(m); ++e) differing += h_cpu[e] != h_cl[e];
      EXPECT_EQ(differing, 0u) << "m " << m << ", blocks [" << first << ", " << last << ")";
      std::printf("m %d, blocks [%u, %u): %zu Gram and rhs entries compared, %zu differ\n", m, first, last,
                  n * (mm + m), differing);
    }
  }
  EXPECT_EQ(device->info().name, "opencl");
  EXPECT_TRUE(device->info().note.empty());
}

TEST(BlockGram, UnavailableOpenClFallsBackToTheCpuWithAReason) {
  const auto engine = make_block_gram(ComputeDevice::choose(BackendOptions{"opencl", "no such device anywhere", 1}));
  EXPECT_EQ(engine->info().kind, DeviceKind::kCpu);
  EXPECT_EQ(engine->info().name, "cpu");
  EXPECT_NE(engine->info().note.find("OpenCL unavailable"), std::string::npos) << engine->info().note;
  EXPECT_NE(engine->info().note.find("no such device anywhere"), std::string::npos) << engine->info().note;
  EXPECT_TRUE(make_block_gram(ComputeDevice::choose(BackendOptions{"cpu", "", 1}))->info().note.empty());
  // auto naming a device that is not there: the CPU engine, saying why (as the integrator does).
  const auto automatic = make_block_gram(ComputeDevice::choose(BackendOptions{"auto", "no such device anywhere", 1}));
  EXPECT_EQ(automatic->info().kind, DeviceKind::kCpu);
  EXPECT_NE(automatic->info().note.find("no usable OpenCL device"), std::string::npos) << automatic->info().note;
  EXPECT_THROW(make_block_gram(ComputeDevice::choose(BackendOptions{"cuda", "", 1})), std::invalid_argument);
}

// Two scans over four blocks and their neighbours (every colour), hits and free points: the posterior with the OpenCL
// engine is the CPU engine's, bit for bit.
TEST(BlockGram, BhmUpdatesWithEitherEngineAgreeExactly) {
  std::string why;
  std::shared_ptr<BlockGramEngine> device = opencl_engine(why);
  if (!device) GTEST_SKIP() << "no OpenCL device with double precision: " << why;
  BhmParams p;
  p.spacing_m = 0.5;
  p.gamma = 4.0;
  p.block_side = 4;
  p.threads = 2;
  BhmModel on_cpu(p), on_device(p, device);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> coord(-1.8, 1.8);
  for (int scan = 0; scan < 2; ++scan) {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    for (int i = 0; i < 300; ++i) {
      const Vec3d x{coord(rng), coord(rng), 0};
      points.push_back(x);
      labels.push_back(x.x + 0.3 * x.y > 0.4 ? 1.0 : 0.0);
    }
    on_cpu.update(points, labels);
    on_device.update(points, labels);
  }
  ASSERT_GE(on_cpu.block_count(), 4u);  // the points' 4 blocks and those their features reach
  ASSERT_EQ(on_device.block_count(), on_cpu.block_count());
  for (size_t b = 0; b < on_cpu.block_count(); ++b) {
    ASSERT_EQ(on_cpu.block_key(b), on_device.block_key(b));
    EXPECT_TRUE(on_cpu.block_mean(b) == on_device.block_mean(b)) << "block " << b;
    EXPECT_TRUE(on_cpu.block_cov(b) == on_device.block_cov(b)) << "block " << b;
  }
  EXPECT_GT(on_cpu.block_mean(0).norm(), 0.1);  // the data moved the weights
  EXPECT_EQ(on_device.backend().name, "opencl");
}

}  // namespace
}  // namespace bgkmap
