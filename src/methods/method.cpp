// Choosing a method by name from the registry (method_descriptor.hpp), and the refusal of a pose
// uncertainty a method would ignore.
#include "bgkmap/methods/method.hpp"

#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/methods/method_descriptor.hpp"

namespace bgkmap {

const std::vector<std::string>& method_names() {
  static const std::vector<std::string> names = [] {
    std::vector<std::string> out;
    for (const MethodDescriptor* method : method_descriptors()) out.push_back(method->name);
    return out;
  }();
  return names;
}

namespace {
std::string pose_uncertainty_refusal(const std::string& name) {
  std::vector<std::string> takers;
  for (const MethodDescriptor* method : method_descriptors())
    if (method->capabilities.pose_uncertainty) takers.push_back(method->name);
  std::string listed;
  for (size_t i = 0; i < takers.size(); ++i)
    listed += (i == 0 ? "" : i + 1 == takers.size() ? " and " : ", ") + takers[i];
  return "the method " + name + " does not use a pose uncertainty (--pose-sigma, --pose-covariance, poses with a "
         "covariance); " + listed + " do";
}
}  // namespace

void MappingMethod::check_pose_uncertainty(const PreparedScan& prepared) const {
  if (prepared.pose_covariance && !uses_pose_uncertainty()) throw std::invalid_argument(pose_uncertainty_refusal(name()));
}

std::unique_ptr<MappingMethod> make_method(const std::string& name, const BuildParams& params,
                                           const MethodParams& method_params, const BackendOptions& backend) {
  method_params.validate();
  check_thread_count(backend.threads);
  if (const MethodDescriptor* descriptor = find_method(name)) {
    std::unique_ptr<MappingMethod> method = descriptor->make(params, method_params, backend);
    if (!params.preprocess.pose_sigma.is_zero() && !method->uses_pose_uncertainty())
      throw std::invalid_argument(pose_uncertainty_refusal(name));
    return method;
  }
  std::string accepted;
  for (const std::string& known : method_names()) accepted += (accepted.empty() ? "" : ", ") + known;
  throw std::invalid_argument("unknown method '" + name + "' (expected one of " + accepted + ")");
}

}  // namespace bgkmap
