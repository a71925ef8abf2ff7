// Map files: the native .bgk format (keeps alpha/beta and every parameter, so a build can be
// resumed and evaluated) and OctoMap's .ot / .bt for octovis and every OctoMap user.
// The .bgk layout is documented in src/io/native_map.cpp (and docs/).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "bgkmap/io/native_map.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

enum class MapFormat {
  kNative,         // .bgk
  kOctomapTree,    // .ot: OcTree holding log-odds of each cell's posterior mean
  kOctomapBinary,  // .bt: occupied / free cells by the map's classification (unknown left out)
};

// From the file extension (case-insensitive); throws InputError naming the file for anything else.
MapFormat map_format_from_path(const std::filesystem::path& file);

// Writes in the format the extension names, atomically (temporary file, then rename).
// Write failures throw std::runtime_error naming the file; an existing file is then left as it was.
// `method`: the method that built the map, which a .bgk records (write_native_map).
void write_map(const std::filesystem::path& file, const BgkMap& map, const std::string& method = "bgkl");

// The same, one format each, whatever the extension (write_native_map: native_map.hpp).
// Cells with evidence only, as log-odds of the posterior mean (probability clamped to
// [1e-6, 1 - 1e-6]); throws std::runtime_error if a cell lies outside OctoMap's +-32768-cell range.
void write_octomap_tree(const std::filesystem::path& file, const BgkMap& map);
// Occupied and free cells by CellPosterior::state; unknown cells left out.
void write_octomap_binary(const std::filesystem::path& file, const BgkMap& map);

}  // namespace bgkmap
