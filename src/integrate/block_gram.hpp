// Weighted Gram matrices of sparse rows, batched by block: for every block b of a batch,
//   gram_b = sum_r weight_r phi_r phi_r^T  (m x m, column-major),  rhs_b = sum_r target_r phi_r
// over the block's rows r, each a few (column, value) entries with distinct columns in [0, m).
// The Bayesian Hilbert map's Phi^T Lambda Phi and Phi^T (y - 1/2) per block of supports
// (methods/bhm/bhm_model.cpp); dense and regular, so it has an OpenCL engine (kernels/block_gram.cl)
// beside the CPU one. Both sum the same products in the same order (entry (i, j) adds
// (weight phi_j) phi_i row by row), so they give the same bits. Internal to the library.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

// The rows of one scan, grouped by block (CSR twice: blocks -> rows -> entries).
struct BlockGramRows {
  int m = 0;                                  // columns (supports) per block
  std::vector<uint32_t> block_row_begin{0};   // block -> first row; one past the last at the end
  std::vector<uint32_t> row_begin{0};         // row -> first entry; one past the last at the end
  std::vector<int32_t> column;                // entry -> column in [0, m)
  std::vector<double> value;                  // entry -> phi
  size_t blocks() const { return block_row_begin.size() - 1; }
  size_t rows() const { return row_begin.size() - 1; }
};

class BlockGramEngine {
 public:
  virtual ~BlockGramEngine() = default;
  virtual BackendInfo info() const = 0;
  // The scan's rows; they stay until the next call (a device keeps its copy).
  virtual void set_rows(const BlockGramRows& rows) = 0;
  // Blocks [first, last) of the rows: weight and target per row (indexed by row, for every row of
  // set_rows), gram (m^2 per block) and rhs (m per block) of those blocks, overwritten.
  virtual void accumulate(uint32_t first, uint32_t last, const std::vector<double>& weight,
                          const std::vector<double>& target, double* gram, double* rhs) = 0;
};

// The CPU engine (OpenMP over blocks).
std::unique_ptr<BlockGramEngine> make_cpu_block_gram(int threads);
// The engine on `device`: the OpenCL engine when the device is a GPU with double precision, or
// OpenCL was asked for (on a CPU device, PoCL, the CPU engine is faster: docs/BENCHMARKS.md, "bhm:
// Phi^T Lambda Phi on OpenCL"); else the CPU engine, its info() carrying the device's note and reason.
std::unique_ptr<BlockGramEngine> make_block_gram(const ComputeDevice& device);

namespace opencl_detail {
// The OpenCL engine on the device the options' filter selects; throws OpenClUnavailable
// (bgkmap/integrate/opencl_integrator.hpp) saying why not.
std::unique_ptr<BlockGramEngine> make_opencl_block_gram(const BackendOptions& options);
}  // namespace opencl_detail

}  // namespace bgkmap
