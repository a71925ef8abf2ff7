#include "integrate/local_gp_batch.hpp"

#include <cstdlib>
#include <stdexcept>

#include "bgkmap/integrate/opencl_integrator.hpp"

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

std::unique_ptr<LocalGpDevice> make_local_gp_device(const BackendOptions& options, std::string& note) {
  note.clear();
  if (options.backend == "cpu") return nullptr;
  if (options.backend != "auto" && options.backend != "opencl")
    throw std::invalid_argument("unknown backend '" + options.backend + "' (expected auto, cpu or opencl)");
  BackendOptions opencl = options;
  opencl.device_filter = opencl_device_filter(options);
  try {
    return opencl_detail::make_opencl_local_gp(opencl, options.backend == "auto");
  } catch (const OpenClUnavailable& e) {
    if (options.backend == "opencl") note = std::string(e.what()) + "; the local models on the CPU path";
    return nullptr;
  }
}

}  // namespace bgkmap
