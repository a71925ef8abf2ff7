#include "cli/tune_yaml.hpp"

#include <nlohmann/json.hpp>
#include <sstream>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "cli/build_options.hpp"

namespace bgkmap::cli {

namespace {

// A JSON scalar is a YAML scalar (strings double-quoted, numbers as the shortest exact decimal).
void write_keys(std::ostream& out, const nlohmann::json& keys) {
  for (const auto& item : keys.items()) out << item.key() << ": " << item.value().dump() << '\n';
}

}  // namespace

std::string tuned_config_yaml(const std::string& method, const BuildParams& params, const MethodParams& method_params,
                              const std::vector<std::string>& comments) {
  std::ostringstream out;
  for (const std::string& line : comments) out << "# " << line << '\n';
  out << "method: " << nlohmann::json(method).dump() << '\n';
  nlohmann::json keys = params_to_json(params);
  // The config takes pose_sigma as the flag's text, not as the report's list.
  if (keys.contains("pose_sigma")) keys["pose_sigma"] = to_string(params.preprocess.pose_sigma);
  write_keys(out, keys);
  write_keys(out, method_params_json(method_params, method));
  return out.str();
}

}  // namespace bgkmap::cli
