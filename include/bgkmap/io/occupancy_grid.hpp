// A map as a planar occupancy grid, written for ROS map_server (a PGM image and its YAML).
//
// Columns: a planar (--2d) map's layer as it is. A 3-D map is projected over the cells whose
// centre z lies in a height band (by default every height, a max-projection): a column is
// occupied if any cell of it in the band is occupied, free if none is occupied and at least one
// is free, else unknown (so the unknown cells of a column never hide its free ones).
// Extent: the bounding box, in x and y, of the cells with evidence that are in the band.
#pragma once

#include <cstdint>
#include <filesystem>
#include <limits>
#include <vector>

#include "bgkmap/io/export_cells.hpp"

namespace bgkmap {

struct HeightBand {
  double z_min = -std::numeric_limits<double>::infinity();
  double z_max = std::numeric_limits<double>::infinity();
  bool contains(double z) const { return z >= z_min && z <= z_max; }
  bool is_every_height() const { return z_min == -std::numeric_limits<double>::infinity() &&
                                        z_max == std::numeric_limits<double>::infinity(); }
};

// The band [z_min, z_max]; throws std::invalid_argument naming --z-min/--z-max unless both are
// finite and z_min <= z_max.
HeightBand height_band_between(double z_min, double z_max);

struct OccupancyGrid {
  double resolution_m = 0;
  int32_t min_x = 0, min_y = 0;  // the cell index of the first column and of the bottom row
  int width = 0, height = 0;
  std::vector<CellState> states;  // row by row from the bottom (min y) up: states[row * width + column]

  CellState at(int column, int row) const { return states[static_cast<size_t>(row) * width + column]; }
  // The world position of the lower-left corner of the bottom-left cell (ROS map_server's origin).
  double origin_x() const { return min_x * resolution_m; }
  double origin_y() const { return min_y * resolution_m; }
};

// Projects `cells` as the header says. Throws InputError naming `output` when there is no cell
// with evidence in the band, or when a band is given for a planar map (which has one layer).
OccupancyGrid project_occupancy(const ExportCells& cells, const HeightBand& band,
                                const std::filesystem::path& output);

// ROS map_server's trinary image values and the YAML thresholds that read exactly them back
// (negate 0: p = (255 - value) / 255; occupied if p > occupied_thresh, free if p < free_thresh).
constexpr unsigned char kRosOccupiedPixel = 0, kRosFreePixel = 254, kRosUnknownPixel = 205;
constexpr double kRosOccupiedThresh = 0.65, kRosFreeThresh = 0.1;

// The YAML written beside a map image: the same path with the extension .yaml.
std::filesystem::path ros_map_yaml_path(const std::filesystem::path& pgm);

// Writes `pgm` (binary P5, the first row the max-y edge) and ros_map_yaml_path(pgm) (image,
// resolution, origin [x, y, 0], negate 0, the thresholds, mode trinary), each atomically.
void write_ros_map(const std::filesystem::path& pgm, const OccupancyGrid& grid);

}  // namespace bgkmap
