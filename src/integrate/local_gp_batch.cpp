#include "integrate/local_gp_batch.hpp"

#include "integrate/device_engine.hpp"

namespace bgkmap {

void LocalGpBatch::add(const std::vector<Vec3d>& train_points, const std::vector<double>& train_labels,
                       const Vec3d& at) {
  const size_t model = size(), n = static_cast<size_t>(max_n);
  count.push_back(static_cast<int32_t>(train_points.size()));
  train.resize((model + 1) * n * 3, 0.0);
  labels.resize((model + 1) * n, 0.0);
  for (size_t i = 0; i < train_points.size(); ++i) {
    double* x = &train[(model * n + i) * 3];
    x[0] = train_points[i].x, x[1] = train_points[i].y, x[2] = train_points[i].z;
    labels[model * n + i] = train_labels[i];
  }
  query.insert(query.end(), {at.x, at.y, at.z});
}

void LocalGpBatch::append(const LocalGpBatch& other) {
  count.insert(count.end(), other.count.begin(), other.count.end());
  train.insert(train.end(), other.train.begin(), other.train.end());
  labels.insert(labels.end(), other.labels.begin(), other.labels.end());
  query.insert(query.end(), other.query.begin(), other.query.end());
}

namespace {

// The CPU engine: the methods' own solve (methods/gp_regression.cpp) does the work.
class CpuLocalGp final : public LocalGpDevice {
 public:
  explicit CpuLocalGp(const ComputeDevice& device)
      : info_(backend_info(DeviceKind::kCpu, "", device.threads(), device.note(), device.reason())) {}
  BackendInfo info() const override { return info_; }
  bool predict(const LocalGpBatch&, const LocalGpCovariance&, double*, double*) override { return false; }

 private:
  BackendInfo info_;
};

}  // namespace

std::unique_ptr<LocalGpDevice> make_local_gp_device(const ComputeDevice& device) {
  return make_engine<LocalGpDevice>(
      device.for_double_precision(),
      [](const ComputeDevice& d) {
        return opencl_detail::make_opencl_local_gp(BackendOptions{"opencl", d.device_filter(), d.threads(), d.kernel_dir()});
      },
      [](const ComputeDevice& d) { return std::make_unique<CpuLocalGp>(d); });
}

}  // namespace bgkmap
