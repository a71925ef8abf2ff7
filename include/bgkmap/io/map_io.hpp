// Map files: the native .bgk format (keeps alpha/beta and every parameter, so a build can be
// resumed and evaluated) and OctoMap's .ot / .bt for octovis and every OctoMap user.
#pragma once

#include <filesystem>

#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

enum class MapFormat {
  kNative,         // .bgk
  kOctomapTree,    // .ot: OcTree holding log-odds of each cell's posterior mean
  kOctomapBinary,  // .bt: occupied / free cells by the map's classification (unknown left out)
};

// From the file extension; throws InputError naming the file for anything else.
MapFormat map_format_from_path(const std::filesystem::path& file);

// Writes in the format the extension names, atomically (temporary file, then rename).
void write_map(const std::filesystem::path& file, const BgkMap& map);

// Reads a native .bgk map; throws InputError naming the file when it is not one, is truncated
// or corrupt, or was written by an unknown format version.
BgkMap read_native_map(const std::filesystem::path& file);

}  // namespace bgkmap
