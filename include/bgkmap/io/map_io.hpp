// Map files: the native .bgk format (keeps alpha/beta and every parameter, so a build can be
// resumed and evaluated), OctoMap's .ot / .bt for octovis and every OctoMap user, and the
// exports for navigation stacks (.pgm + .yaml, .ply, .pcd: map_export.hpp), which bgkmap writes
// but never reads. The .bgk layout is documented in src/io/native_map.cpp (and docs/).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "bgkmap/io/native_map.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

enum class MapFormat {
  kNative,         // .bgk
  kOctomapTree,    // .ot: OcTree of log-odds (TreeValues says of what)
  kOctomapBinary,  // .bt: occupied / free cells by the map's classification (unknown left out)
  kRosMap,         // .pgm (+ .yaml beside it): ROS map_server occupancy grid
  kPlyCloud,       // .ply: occupied cells with probability and variance
  kPcdCloud,       // .pcd: the same as a PCL point cloud
};

// The formats bgkmap writes for other tools and does not read back: .pgm, .ply, .pcd.
bool is_export_format(MapFormat format);

// From the file extension (case-insensitive); throws InputError naming the file for anything else.
MapFormat map_format_from_path(const std::filesystem::path& file);
// The same for a map to read: an export is refused with an InputError naming the file.
MapFormat readable_map_format_from_path(const std::filesystem::path& file);

// What a .ot written by bgkmap holds (`--ot-values`). OctoMap's tools call a node occupied when its
// probability is at least 0.5 (the file stores no threshold) and a cell without a node unknown.
enum class TreeValues {
  // The cells the map classifies occupied or free, each with a probability that OctoMap's 0.5
  // classifies as the map does (the method's own probability where it already does: always with
  // thresholds on either side of 0.5); the cells it calls unknown are left out. What OctoMap's
  // tools (octovis, octomap_server, MoveIt) should read.
  kClassified,
  // Every cell the map has evidence for, with the method's probability (the posterior mean, or a
  // probability map's value): what `bgkmap eval` scores. OctoMap's tools then call every cell
  // above 0.5 occupied, also those the map calls unknown.
  kMean,
};
const char* to_string(TreeValues values);
// "classified" or "mean"; throws std::invalid_argument naming the accepted values otherwise.
TreeValues tree_values_from_string(const std::string& name);


// Before any work: the format is known and every file it writes can be written (check_output_path;
// a .pgm's .yaml too).
void check_map_output(const std::filesystem::path& file);

// Writes in the format the extension names, atomically (temporary file, then rename); an export
// of a 3-D map's .pgm projects every height (occupancy_grid.hpp).
// Write failures throw std::runtime_error naming the file; an existing file is then left as it was.
// `method`: the method that built the map, which a .bgk records (write_native_map); `ot_values`:
// what a .ot holds.
void write_map(const std::filesystem::path& file, const BgkMap& map, const std::string& method = "bgkl",
               TreeValues ot_values = TreeValues::kClassified);

// The same, one format each, whatever the extension (write_native_map: native_map.hpp).
// kClassified: the cells CellPosterior::state calls occupied or free; kMean: every cell with
// evidence, as log-odds of its posterior mean (probability clamped to [1e-6, 1 - 1e-6]). Throws
// std::runtime_error if a cell lies outside OctoMap's +-32768-cell range.
void write_octomap_tree(const std::filesystem::path& file, const BgkMap& map,
                        TreeValues values = TreeValues::kClassified);
// Occupied and free cells by CellPosterior::state; unknown cells left out.
void write_octomap_binary(const std::filesystem::path& file, const BgkMap& map);

}  // namespace bgkmap
