// Built-in scenes. Their geometry is fixed (generated from constant seeds), so a preset is a
// stable benchmark; the run's seed only drives sensor noise and dropout.
//   structured    rooms with walls, doors, ceiling and furniture, ~10 x 7 x 2 m, VLP-16, 12 scans
//   unstructured  a forest patch on uneven ground (trunks, canopies, bushes, rocks), same size
//   campus        ~600 x 350 m of roads, buildings, trees, lamp posts and parked cars;
//                 3000 VLP-16 scans along a 2 km loop: the large-scale benchmark
//   dynamic       two ~5 x 5 m rooms; a door between them opens, a parked car leaves, two people
//                 walk to and fro; 40 scans of a 1-degree VLP-16 looping in the west room
#pragma once

#include <string>
#include <vector>

#include "bgkmap/sim/spec.hpp"

namespace bgkmap::sim {

const std::vector<std::string>& preset_names();
bool is_preset(const std::string& name);
// Throws std::invalid_argument naming the presets for an unknown name.
SimulationSpec make_preset(const std::string& name);

// One generator per preset file, defined in its own translation unit.
SimulationSpec make_structured_preset();
SimulationSpec make_unstructured_preset();
SimulationSpec make_campus_preset();
SimulationSpec make_dynamic_preset();

}  // namespace bgkmap::sim
