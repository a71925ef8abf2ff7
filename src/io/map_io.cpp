// Map file formats by extension; the writers live in native_map.cpp and octomap_export.cpp.
#include "bgkmap/io/map_io.hpp"

#include <algorithm>
#include <cctype>
#include <stdexcept>
#include <string>

#include "bgkmap/io/errors.hpp"

namespace bgkmap {

MapFormat map_format_from_path(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (ext == ".bgk") return MapFormat::kNative;
  if (ext == ".ot") return MapFormat::kOctomapTree;
  if (ext == ".bt") return MapFormat::kOctomapBinary;
  const std::string found = ext.empty() ? "no extension" : "extension '" + file.extension().string() + "'";
  throw InputError(file, "unknown map format (" + found + "; expected .bgk, .ot or .bt)");
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
  }
}

}  // namespace bgkmap
