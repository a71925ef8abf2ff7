#include "integrate/block_gram.hpp"

#include <omp.h>

#include <algorithm>
#include <cstdlib>
#include <stdexcept>

#include "bgkmap/integrate/opencl_integrator.hpp"

namespace bgkmap {

namespace {

class CpuBlockGram final : public BlockGramEngine {
 public:
  explicit CpuBlockGram(int threads) : threads_(threads > 0 ? threads : omp_get_max_threads()) {}

  BackendInfo info() const override { return {"cpu", "", threads_, ""}; }
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
  const BlockGramRows* rows_ = nullptr;
};

}  // namespace

std::unique_ptr<BlockGramEngine> make_cpu_block_gram(int threads) { return std::make_unique<CpuBlockGram>(threads); }

std::unique_ptr<BlockGramEngine> make_block_gram(const BackendOptions& options) {
  if (options.backend == "cpu") return make_cpu_block_gram(options.threads);
  if (options.backend != "auto" && options.backend != "opencl")
    throw std::invalid_argument("unknown backend '" + options.backend + "' (expected auto, cpu or opencl)");
  BackendOptions opencl = options;
  opencl.device_filter = opencl_device_filter(options);
  try {
    std::unique_ptr<BlockGramEngine> engine = opencl_detail::make_opencl_block_gram(opencl, options.backend == "auto");
    return engine ? std::move(engine) : make_cpu_block_gram(options.threads);
  } catch (const OpenClUnavailable& e) {
    // The same sums on the CPU; the caller says why once.
    class Substitute final : public BlockGramEngine {
     public:
      Substitute(std::unique_ptr<BlockGramEngine> inner, std::string note)
          : inner_(std::move(inner)), note_(std::move(note)) {}
      BackendInfo info() const override {
        BackendInfo b = inner_->info();
        b.note = note_;
        return b;
      }
      void set_rows(const BlockGramRows& rows) override { inner_->set_rows(rows); }
      void accumulate(uint32_t first, uint32_t last, const std::vector<double>& weight,
                      const std::vector<double>& target, double* gram, double* rhs) override {
        inner_->accumulate(first, last, weight, target, gram, rhs);
      }

     private:
      std::unique_ptr<BlockGramEngine> inner_;
      std::string note_;
    };
    if (options.backend == "auto") return make_cpu_block_gram(options.threads);  // no GPU: the CPU engine is the choice
    return std::make_unique<Substitute>(make_cpu_block_gram(options.threads),
                                        std::string("OpenCL unavailable, using the CPU path: ") + e.what());
  }
}

}  // namespace bgkmap
