// Range sensor models. Sensor frame: x forward, y left, z up; a beam's direction is a unit
// vector in that frame, rotated into the world by the scan pose.
#pragma once

#include <string>
#include <vector>

#include "bgkmap/sim/vec_math.hpp"

namespace bgkmap::sim {

enum class SensorKind {
  kSpinning,  // rotating lidar: `rings` elevations x azimuth steps over horizontal_fov_deg
  kPinhole,   // depth camera: width x height pixels through a pinhole, max range along the beam
};

struct SensorModel {
  std::string name = "custom";
  SensorKind kind = SensorKind::kSpinning;
  // Spinning: rings evenly spaced from elevation_min_deg to elevation_max_deg (one ring: the
  // minimum); azimuths every azimuth_resolution_deg, centred on x, across horizontal_fov_deg.
  int rings = 16;
  double elevation_min_deg = -15, elevation_max_deg = 15;
  double azimuth_resolution_deg = 0.2;
  double horizontal_fov_deg = 360;
  // Pinhole: image size and vertical field of view (horizontal_fov_deg is shared).
  int width = 160, height = 120;
  double vertical_fov_deg = 58;

  double max_range_m = 100;          // surfaces farther away give no return
  double range_noise_sigma_m = 0.0;  // Gaussian noise added to each returned range
  double dropout = 0.0;              // probability that a return is lost (written as NaN)

  // Throws std::invalid_argument with a one-line reason when a value is out of range.
  void validate() const;
  size_t beam_count() const;
};

// "vlp16", "planar", "depth-camera"; throws std::invalid_argument naming the choices otherwise.
SensorModel sensor_preset(const std::string& name);
const std::vector<std::string>& sensor_preset_names();

// Unit beam directions in the sensor frame, ring by ring (row by row for a camera).
std::vector<Vec3d> beam_directions(const SensorModel& sensor);

const char* to_string(SensorKind kind);
SensorKind sensor_kind_from_string(const std::string& name);  // throws std::invalid_argument

}  // namespace bgkmap::sim
