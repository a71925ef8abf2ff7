// The OpenCL engine of integrate/block_gram.hpp: kernels/block_gram.cl, one work-group per block.
// The scan's rows go over once (set_rows); each accumulate() sends its rows' weights and targets
// and reads its blocks' Gram matrices back. A device fault mid-run hands the work to the CPU
// engine for the rest of the run (the same sums), with the reason in info().note.
#include <algorithm>
#include <string>
#include <utility>

#include "integrate/block_gram.hpp"
#include "opencl_runtime.hpp"

namespace bgkmap::opencl_detail {

namespace {

// Gram bytes one launch may read back (larger batches go in several launches).
constexpr size_t kMaxLaunchGramBytes = size_t(256) << 20;
// Rows staged per tile at most (local memory: chunk x m doubles).
constexpr size_t kMaxChunk = 32;

class OpenClBlockGram final : public BlockGramEngine {
 public:
  explicit OpenClBlockGram(const BackendOptions& options) : threads_(options.threads) {
    OpenClOptions opencl;
    opencl.device_filter = options.device_filter;
    opencl.kernel_dir = options.kernel_dir;
    program_ = device_program(opencl, KernelProgram::kBlockGram);
    try {
      queue_ = cl::CommandQueue(program_->context, program_->device);
      kernel_ = cl::Kernel(program_->program, "block_gram");
      const size_t kernel_group = kernel_.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(program_->device);
      max_group_ = std::max<size_t>(1, std::min({kernel_group, program_->info.max_work_group_size, kMaxGroupSize}));
    } catch (const cl::Error& e) {
      throw OpenClUnavailable("cannot set up the block Gram kernel on '" + program_->info.full_name() +
                              "': " + cl_error_name(e.err()));
    }
  }

  BackendInfo info() const override {
    if (cpu_) {
      BackendInfo b = cpu_->info();
      b.note = note_;
      return b;
    }
    return backend_info(DeviceKind::kOpenCl, program_->info.full_name(), threads_);
  }

  void set_rows(const BlockGramRows& rows) override {
    rows_ = &rows;
    if (cpu_) return cpu_->set_rows(rows);
    try {
      upload(block_row_begin_, rows.block_row_begin);
      upload(row_begin_, rows.row_begin);
      upload(column_, rows.column);
      upload(value_, rows.value);
      reserve(weight_, rows.rows() * sizeof(double));
      reserve(target_, rows.rows() * sizeof(double));
      queue_.finish();  // the caller may change its rows once this returns
    } catch (const cl::Error& e) {
      fall_back(e);
    }
  }

  void accumulate(uint32_t first, uint32_t last, const std::vector<double>& weight, const std::vector<double>& target,
                  double* gram, double* rhs) override {
    if (!cpu_) {
      try {
        return device_accumulate(first, last, weight, target, gram, rhs);
      } catch (const cl::Error& e) {
        fall_back(e);
      }
    }
    cpu_->accumulate(first, last, weight, target, gram, rhs);
  }

 private:
  template <typename T>
  void upload(GrowingBuffer& b, const std::vector<T>& data) {
    b.upload(program_->context, queue_, data.data(), data.size());
  }
  void reserve(GrowingBuffer& b, size_t bytes) { b.reserve(program_->context, bytes); }

  void device_accumulate(uint32_t first, uint32_t last, const std::vector<double>& weight,
                         const std::vector<double>& target, double* gram, double* rhs) {
    const BlockGramRows& r = *rows_;
    const size_t m = static_cast<size_t>(r.m);
    const size_t group = std::min(max_group_, m);
    const size_t local_bytes = static_cast<size_t>(program_->info.local_memory_bytes);
    const size_t chunk = std::max<size_t>(1, std::min(kMaxChunk, local_bytes / 2 / (m * sizeof(double))));
    if (chunk * m * sizeof(double) > local_bytes) throw cl::Error(CL_OUT_OF_RESOURCES, "local memory");
    const size_t per_launch = std::max<size_t>(1, kMaxLaunchGramBytes / (m * m * sizeof(double)));
    // This range's rows' weights and targets, at their rows' places.
    const uint32_t row0 = r.block_row_begin[first], row1 = r.block_row_begin[last];
    if (row1 > row0) {
      queue_.enqueueWriteBuffer(weight_.buffer, CL_FALSE, row0 * sizeof(double), (row1 - row0) * sizeof(double),
                                weight.data() + row0);
      queue_.enqueueWriteBuffer(target_.buffer, CL_FALSE, row0 * sizeof(double), (row1 - row0) * sizeof(double),
                                target.data() + row0);
    }
    for (uint32_t b0 = first; b0 < last; b0 += static_cast<uint32_t>(per_launch)) {
      const size_t n = std::min<size_t>(per_launch, last - b0);
      reserve(gram_, n * m * m * sizeof(double));
      reserve(rhs_, n * m * sizeof(double));
      int arg = 0;
      kernel_.setArg(arg++, static_cast<cl_int>(m));
      kernel_.setArg(arg++, static_cast<cl_uint>(b0));
      kernel_.setArg(arg++, static_cast<cl_uint>(chunk));
      kernel_.setArg(arg++, block_row_begin_.buffer);
      kernel_.setArg(arg++, row_begin_.buffer);
      kernel_.setArg(arg++, column_.buffer);
      kernel_.setArg(arg++, value_.buffer);
      kernel_.setArg(arg++, weight_.buffer);
      kernel_.setArg(arg++, target_.buffer);
      kernel_.setArg(arg++, gram_.buffer);
      kernel_.setArg(arg++, rhs_.buffer);
      kernel_.setArg(arg++, cl::Local(chunk * m * sizeof(double)));
      queue_.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(n * group), cl::NDRange(group));
      const size_t done = b0 - first;
      queue_.enqueueReadBuffer(gram_.buffer, CL_FALSE, 0, n * m * m * sizeof(double), gram + done * m * m);
      queue_.enqueueReadBuffer(rhs_.buffer, CL_TRUE, 0, n * m * sizeof(double), rhs + done * m);
    }
  }

  void fall_back(const cl::Error& e) {
    note_ = "the OpenCL device failed (" + std::string(e.what()) + ": " + cl_error_name(e.err()) +
            "); the rest of the run on the CPU path";
    cpu_ = make_cpu_block_gram(threads_);
    if (rows_) cpu_->set_rows(*rows_);
  }

  int threads_;
  std::shared_ptr<const DeviceProgram> program_;
  cl::CommandQueue queue_;
  cl::Kernel kernel_;
  size_t max_group_ = 1;
  const BlockGramRows* rows_ = nullptr;
  GrowingBuffer block_row_begin_, row_begin_, column_, value_, weight_, target_, gram_, rhs_;
  std::unique_ptr<BlockGramEngine> cpu_;  // after a device fault
  std::string note_;
};

}  // namespace

std::unique_ptr<BlockGramEngine> make_opencl_block_gram(const BackendOptions& options) {
  return std::make_unique<OpenClBlockGram>(options);
}

}  // namespace bgkmap::opencl_detail
