#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>

#include "bgkmap/build/build_session.hpp"
#include "bgkmap/core/params_io.hpp"

namespace bgkmap {

BuildParams resumed_params(const BuildParams& stored, const BuildParams& wanted) {
  // Thresholds only classify cells for outputs; everything else fixes what alpha/beta mean.
  // A key only one side has (planar maps' keys) is a change too.
  const nlohmann::json a = params_to_json(stored), b = params_to_json(wanted);
  nlohmann::json keys = a;
  keys.update(b);
  for (const auto& item : keys.items()) {
    const std::string& key = item.key();
    if (key == "occupied_threshold" || key == "free_threshold" || key == "var_threshold") continue;
    const nlohmann::json was = a.contains(key) ? a.at(key) : nlohmann::json();
    const nlohmann::json asked = b.contains(key) ? b.at(key) : nlohmann::json();
    if (was != asked) {
      const auto shown = [](const nlohmann::json& v) { return v.is_null() ? std::string("the default") : v.dump(); };
      throw std::invalid_argument("cannot change '" + key + "' when resuming a map (stored " + shown(was) +
                                  ", asked " + shown(asked) + ")");
    }
  }
  BuildParams resumed = stored;
  resumed.classify = wanted.classify;
  resumed.validate();
  return resumed;
}

}  // namespace bgkmap
