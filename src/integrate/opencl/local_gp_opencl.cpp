// The OpenCL device of integrate/local_gp_batch.hpp: kernels/local_gp.cl, one work-group per
// model, its K, L^-1 k* and L^-1 y in local memory. A device fault makes predict() return false
// with the reason in info().note; the caller solves the rest on the CPU.
#include <algorithm>
#include <string>

#include "integrate/local_gp_batch.hpp"
#include "opencl_runtime.hpp"

namespace bgkmap::opencl_detail {

namespace {

// Models per launch at most (their inputs and outputs are staged in one set of buffers).
constexpr size_t kMaxModelsPerLaunch = 16384;
// Work-items per model: the Cholesky's trailing updates are (n - j)^2 / 2 entries for n <= 2k.
constexpr size_t kGroupSize = 64;

class OpenClLocalGp final : public LocalGpDevice {
 public:
  OpenClLocalGp(const BackendOptions& options) : threads_(options.threads) {
    OpenClOptions opencl;
    opencl.device_filter = options.device_filter;
    opencl.kernel_dir = options.kernel_dir;
    program_ = device_program(opencl, KernelProgram::kLocalGp);
    try {
      queue_ = cl::CommandQueue(program_->context, program_->device);
      kernel_ = cl::Kernel(program_->program, "local_gp_predict");
      const size_t kernel_group = kernel_.getWorkGroupInfo<CL_KERNEL_WORK_GROUP_SIZE>(program_->device);
      group_ = std::max<size_t>(1, std::min({kernel_group, program_->info.max_work_group_size, kGroupSize}));
      if (program_->info.type == "CPU") group_ = 1;
    } catch (const cl::Error& e) {
      throw OpenClUnavailable("cannot set up the local GP kernel on '" + program_->info.full_name() +
                              "': " + cl_error_name(e.err()));
    }
  }

  BackendInfo info() const override {
    return backend_info(failed_ ? DeviceKind::kCpu : DeviceKind::kOpenCl, program_->info.full_name(), threads_, note_);
  }

  bool predict(const LocalGpBatch& batch, const LocalGpCovariance& covariance, double* mean,
               double* variance) override {
    if (failed_) return false;
    try {
      const size_t n = static_cast<size_t>(batch.max_n);
      const size_t local_bytes = (n * n + 2 * n) * sizeof(double) + sizeof(cl_int);
      if (local_bytes > static_cast<size_t>(program_->info.local_memory_bytes))
        throw cl::Error(CL_OUT_OF_RESOURCES, "local memory for a local model");
      for (size_t first = 0; first < batch.size(); first += kMaxModelsPerLaunch) {
        const size_t models = std::min(kMaxModelsPerLaunch, batch.size() - first);
        upload(count_, batch.count.data() + first, models);
        upload(train_, batch.train.data() + first * n * 3, models * n * 3);
        upload(labels_, batch.labels.data() + first * n, models * n);
        upload(query_, batch.query.data() + first * 3, models * 3);
        reserve(mean_, models * sizeof(double));
        reserve(variance_, models * sizeof(double));
        int arg = 0;
        kernel_.setArg(arg++, static_cast<cl_int>(n));
        kernel_.setArg(arg++, static_cast<cl_int>(covariance.covariance));
        kernel_.setArg(arg++, covariance.ell_m);
        kernel_.setArg(arg++, covariance.signal_var);
        kernel_.setArg(arg++, covariance.noise_var);
        kernel_.setArg(arg++, count_.buffer);
        kernel_.setArg(arg++, train_.buffer);
        kernel_.setArg(arg++, labels_.buffer);
        kernel_.setArg(arg++, query_.buffer);
        kernel_.setArg(arg++, mean_.buffer);
        kernel_.setArg(arg++, variance_.buffer);
        kernel_.setArg(arg++, cl::Local(n * n * sizeof(double)));
        kernel_.setArg(arg++, cl::Local(n * sizeof(double)));
        kernel_.setArg(arg++, cl::Local(n * sizeof(double)));
        kernel_.setArg(arg++, cl::Local(sizeof(cl_int)));
        queue_.enqueueNDRangeKernel(kernel_, cl::NullRange, cl::NDRange(models * group_), cl::NDRange(group_));
        queue_.enqueueReadBuffer(mean_.buffer, CL_FALSE, 0, models * sizeof(double), mean + first);
        queue_.enqueueReadBuffer(variance_.buffer, CL_TRUE, 0, models * sizeof(double), variance + first);
      }
      return true;
    } catch (const cl::Error& e) {
      failed_ = true;
      note_ = "the OpenCL device failed (" + std::string(e.what()) + ": " + cl_error_name(e.err()) +
              "); the rest of the local models on the CPU path";
      return false;
    }
  }

 private:
  template <typename T>
  void upload(GrowingBuffer& b, const T* data, size_t count) {
    b.upload(program_->context, queue_, data, count);
  }
  void reserve(GrowingBuffer& b, size_t bytes) { b.reserve(program_->context, bytes); }

  int threads_;
  std::shared_ptr<const DeviceProgram> program_;
  cl::CommandQueue queue_;
  cl::Kernel kernel_;
  size_t group_ = 1;
  GrowingBuffer count_, train_, labels_, query_, mean_, variance_;
  bool failed_ = false;
  std::string note_;
};

}  // namespace

std::unique_ptr<LocalGpDevice> make_opencl_local_gp(const BackendOptions& options) {
  return std::make_unique<OpenClLocalGp>(options);
}

}  // namespace bgkmap::opencl_detail
