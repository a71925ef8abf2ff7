// A complete simulation: scene, sensor, trajectory, seed and truth resolution. It is what a scene
// file describes and what `simulate` writes back as DIR/scene.yaml, so rerunning that file
// reproduces the run exactly. Schema: docs/SIMULATOR.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "bgkmap/sim/scene.hpp"
#include "bgkmap/sim/sensor.hpp"
#include "bgkmap/sim/trajectory.hpp"

namespace bgkmap::sim {

struct SimulationSpec {
  std::string name = "custom";
  Scene scene;
  SensorModel sensor;
  Trajectory trajectory;
  uint64_t seed = 1;                // noise and dropout; the geometry never depends on it
  double truth_resolution_m = 0.1;  // cell size of truth.bt; 0: no truth.bt

  // Throws std::invalid_argument with a one-line reason.
  void validate() const;
};

// Throws InputError naming the file (and the YAML line where there is one) on bad input.
SimulationSpec load_spec(const std::filesystem::path& file);
SimulationSpec parse_spec(const std::string& yaml_text, const std::string& source_name);
// A file holding just a sensor mapping (the scene file's `sensor:` schema); InputError as above.
SensorModel load_sensor(const std::filesystem::path& file);

// Every field written out (sensor expanded, not by preset name); doubles in their shortest form
// that reads back to the same value.
std::string spec_to_yaml(const SimulationSpec& spec);
void save_spec(const std::filesystem::path& file, const SimulationSpec& spec);  // atomic

}  // namespace bgkmap::sim
