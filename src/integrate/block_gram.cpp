#include "integrate/block_gram.hpp"

#include <omp.h>

#include <algorithm>
#include <string>
#include <utility>

#include "integrate/device_engine.hpp"

namespace bgkmap {

namespace {

class CpuBlockGram final : public BlockGramEngine {
 public:
  explicit CpuBlockGram(int threads, std::string note = "", std::string reason = "")
      : threads_(threads > 0 ? threads : omp_get_max_threads()), note_(std::move(note)), reason_(std::move(reason)) {}

  BackendInfo info() const override { return backend_info(DeviceKind::kCpu, "", threads_, note_, reason_); }
  void set_rows(const BlockGramRows& rows) override { rows_ = &rows; }

  void accumulate(uint32_t first, uint32_t last, const std::vector<double>& weight, const std::vector<double>& target,
                  double* gram, double* rhs) override {
    const BlockGramRows& r = *rows_;
    const size_t m = static_cast<size_t>(r.m);
#pragma omp parallel for schedule(dynamic) num_threads(threads_)
    for (int64_t b = first; b < int64_t{last}; ++b) {
      double* g = gram + (b - first) * m * m;
      double* h = rhs + (b - first) * m;
      std::fill(g, g + m * m, 0.0);
      std::fill(h, h + m, 0.0);
      for (uint32_t row = r.block_row_begin[b]; row < r.block_row_begin[b + 1]; ++row)
        for (uint32_t u = r.row_begin[row]; u < r.row_begin[row + 1]; ++u) {
          const double phi_j = r.value[u];
          const size_t j = static_cast<size_t>(r.column[u]);
          h[j] += phi_j * target[row];
          const double scaled = weight[row] * phi_j;
          for (uint32_t v = r.row_begin[row]; v < r.row_begin[row + 1]; ++v) g[r.column[v] + j * m] += scaled * r.value[v];
        }
    }
  }

 private:
  int threads_;
  std::string note_, reason_;  // the device's: why the CPU engine runs
  const BlockGramRows* rows_ = nullptr;
};

}  // namespace

std::unique_ptr<BlockGramEngine> make_cpu_block_gram(int threads) { return std::make_unique<CpuBlockGram>(threads); }

std::unique_ptr<BlockGramEngine> make_block_gram(const ComputeDevice& device) {
  return make_engine<BlockGramEngine>(
      device.for_double_precision(),
      [](const ComputeDevice& d) {
        return opencl_detail::make_opencl_block_gram(BackendOptions{"opencl", d.device_filter(), d.threads(), d.kernel_dir()});
      },
      [](const ComputeDevice& d) { return std::make_unique<CpuBlockGram>(d.threads(), d.note(), d.reason()); });
}

}  // namespace bgkmap
