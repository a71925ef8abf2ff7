// Map file formats by extension; the writers live in native_map.cpp, octomap_export.cpp and map_export.cpp.
#include "bgkmap/io/map_io.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_export.hpp"

namespace bgkmap {

MapFormat map_format_from_path(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".bgk") return MapFormat::kNative;
  if (ext == ".ot") return MapFormat::kOctomapTree;
  if (ext == ".bt") return MapFormat::kOctomapBinary;
  if (ext == ".pgm") return MapFormat::kRosMap;
  if (ext == ".ply") return MapFormat::kPlyCloud;
  if (ext == ".pcd") return MapFormat::kPcdCloud;
  const std::string found = ext.empty() ? "no extension" : "extension '" + file.extension().string() + "'";
  throw InputError(file, "unknown map format (" + found + "; expected .bgk, .ot, .bt, or an export: .pgm, .ply, .pcd)");
}

bool is_export_format(MapFormat format) {
  return format == MapFormat::kRosMap || format == MapFormat::kPlyCloud || format == MapFormat::kPcdCloud;
}

MapFormat readable_map_format_from_path(const std::filesystem::path& file) {
  const MapFormat format = map_format_from_path(file);
  if (is_export_format(format))
    throw InputError(file, "an export for other tools (.pgm, .ply, .pcd), which bgkmap does not read: give the .bgk, .ot or .bt");
  return format;
}

void check_map_output(const std::filesystem::path& file) {
  const MapFormat format = map_format_from_path(file);
  check_output_path(file);
  if (format == MapFormat::kRosMap) check_output_path(ros_map_yaml_path(file));
}

const char* to_string(TreeValues values) { return values == TreeValues::kMean ? "mean" : "classified"; }

TreeValues tree_values_from_string(const std::string& name) {
  if (name == "classified") return TreeValues::kClassified;
  if (name == "mean") return TreeValues::kMean;
  throw std::invalid_argument("unknown --ot-values '" + name + "' (expected classified or mean)");
}

void write_map(const std::filesystem::path& file, const BgkMap& map, const std::string& method, TreeValues ot_values) {
  switch (map_format_from_path(file)) {
    case MapFormat::kNative: return write_native_map(file, map, {}, method);
    case MapFormat::kOctomapTree: return write_octomap_tree(file, map, ot_values);
    case MapFormat::kOctomapBinary: return write_octomap_binary(file, map);
    case MapFormat::kRosMap:
    case MapFormat::kPlyCloud:
    case MapFormat::kPcdCloud: return write_map_export(file, export_cells(map));
  }
}

}  // namespace bgkmap
