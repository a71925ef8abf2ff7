#include "bgkmap/sim/sensor.hpp"

#include <cmath>
#include <stdexcept>

namespace bgkmap::sim {

namespace {
constexpr double kDeg = M_PI / 180.0;

// Azimuth samples across the field of view. A full circle has no duplicate at +180 degrees;
// a partial one includes both edges.
int azimuth_steps(const SensorModel& s) {
  if (s.horizontal_fov_deg >= 360) return static_cast<int>(std::lround(360.0 / s.azimuth_resolution_deg));
  return static_cast<int>(std::floor(s.horizontal_fov_deg / s.azimuth_resolution_deg + 1e-9)) + 1;
}

std::string joined_names() {
  std::string out;
  for (const auto& n : sensor_preset_names()) out += (out.empty() ? "" : ", ") + n;
  return out;
}
}  // namespace

const char* to_string(SensorKind kind) { return kind == SensorKind::kSpinning ? "spinning" : "pinhole"; }

SensorKind sensor_kind_from_string(const std::string& name) {
  if (name == "spinning") return SensorKind::kSpinning;
  if (name == "pinhole") return SensorKind::kPinhole;
  throw std::invalid_argument("unknown sensor kind '" + name + "' (expected spinning or pinhole)");
}

const std::vector<std::string>& sensor_preset_names() {
  static const std::vector<std::string> names{"vlp16", "planar", "depth-camera"};
  return names;
}

SensorModel sensor_preset(const std::string& name) {
  SensorModel s;
  s.name = name;
  if (name == "vlp16") {
    // Velodyne VLP-16 datasheet: 16 rings over +-15 deg, 0.2 deg at 10 Hz, 100 m, +-3 cm.
    s.kind = SensorKind::kSpinning;
    s.rings = 16;
    s.elevation_min_deg = -15;
    s.elevation_max_deg = 15;
    s.azimuth_resolution_deg = 0.2;
    s.horizontal_fov_deg = 360;
    s.max_range_m = 100;
    s.range_noise_sigma_m = 0.015;
  } else if (name == "planar") {
    // A 2-D scanner like the Hokuyo UTM-30LX: 270 deg at 0.25 deg, 30 m.
    s.kind = SensorKind::kSpinning;
    s.rings = 1;
    s.elevation_min_deg = s.elevation_max_deg = 0;
    s.azimuth_resolution_deg = 0.25;
    s.horizontal_fov_deg = 270;
    s.max_range_m = 30;
    s.range_noise_sigma_m = 0.01;
  } else if (name == "depth-camera") {
    // A RealSense-D435-like camera at a reduced 160 x 120 image: 87 x 58 deg, 10 m.
    s.kind = SensorKind::kPinhole;
    s.width = 160;
    s.height = 120;
    s.horizontal_fov_deg = 87;
    s.vertical_fov_deg = 58;
    s.max_range_m = 10;
    s.range_noise_sigma_m = 0.01;
  } else {
    throw std::invalid_argument("unknown sensor '" + name + "' (expected " + joined_names() + ")");
  }
  return s;
}

void SensorModel::validate() const {
  auto require = [](bool ok, const std::string& what) {
    if (!ok) throw std::invalid_argument("sensor: " + what);
  };
  require(std::isfinite(max_range_m) && max_range_m > 0, "max_range must be positive");
  require(std::isfinite(range_noise_sigma_m) && range_noise_sigma_m >= 0, "range_noise_sigma must be >= 0");
  require(dropout >= 0 && dropout <= 1, "dropout must be a probability in [0, 1]");
  require(horizontal_fov_deg > 0 && horizontal_fov_deg <= 360, "horizontal_fov_deg must be in (0, 360]");
  if (kind == SensorKind::kSpinning) {
    require(rings >= 1 && rings <= 4096, "rings must be in [1, 4096]");
    require(elevation_min_deg >= -90 && elevation_max_deg <= 90 && elevation_min_deg <= elevation_max_deg,
            "elevations must satisfy -90 <= elevation_min_deg <= elevation_max_deg <= 90");
    require(azimuth_resolution_deg >= 0.001 && azimuth_resolution_deg <= 360, "azimuth_resolution_deg must be in [0.001, 360]");
  } else {
    require(width >= 1 && height >= 1 && width <= 8192 && height <= 8192, "width and height must be in [1, 8192]");
    require(horizontal_fov_deg < 180 && vertical_fov_deg > 0 && vertical_fov_deg < 180,
            "a pinhole camera's fields of view must be in (0, 180) degrees");
  }
}

size_t SensorModel::beam_count() const {
  if (kind == SensorKind::kPinhole) return static_cast<size_t>(width) * height;
  return static_cast<size_t>(rings) * azimuth_steps(*this);
}

std::vector<Vec3d> beam_directions(const SensorModel& s) {
  s.validate();
  std::vector<Vec3d> dirs;
  dirs.reserve(s.beam_count());
  if (s.kind == SensorKind::kPinhole) {
    // Through pixel centres; image rows run top to bottom, columns left to right.
    const double fx = 0.5 * s.width / std::tan(0.5 * s.horizontal_fov_deg * kDeg);
    const double fy = 0.5 * s.height / std::tan(0.5 * s.vertical_fov_deg * kDeg);
    for (int v = 0; v < s.height; ++v)
      for (int u = 0; u < s.width; ++u)
        dirs.push_back(normalized({1.0, -(u + 0.5 - 0.5 * s.width) / fx, -(v + 0.5 - 0.5 * s.height) / fy}));
    return dirs;
  }
  const int steps = azimuth_steps(s);
  const double first_azimuth = s.horizontal_fov_deg >= 360 ? -180.0 : -0.5 * s.horizontal_fov_deg;
  for (int r = 0; r < s.rings; ++r) {
    const double elevation =
        s.rings == 1 ? s.elevation_min_deg
                     : s.elevation_min_deg + (s.elevation_max_deg - s.elevation_min_deg) * r / (s.rings - 1);
    const double ce = std::cos(elevation * kDeg), se = std::sin(elevation * kDeg);
    for (int a = 0; a < steps; ++a) {
      const double azimuth = (first_azimuth + a * s.azimuth_resolution_deg) * kDeg;
      dirs.push_back({ce * std::cos(azimuth), ce * std::sin(azimuth), se});
    }
  }
  return dirs;
}

}  // namespace bgkmap::sim
