// The native .bgk map file: alpha/beta of every touched block and every parameter, so that a
// build can be resumed, queried and evaluated. Part of the core library (bgkmap::core); the
// layout is documented in src/io/native_map.cpp.
#pragma once

#include <cstdint>
#include <filesystem>

#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// The .bgk format version this build writes; it reads this one and no other.
inline constexpr uint32_t kNativeMapFormatVersion = 1;

// Writes atomically (temporary file, then rename). Write failures throw std::runtime_error naming
// the file; an existing file is then left as it was.
void write_native_map(const std::filesystem::path& file, const BgkMap& map);

// Reads a native .bgk map; throws InputError naming the file when it is not one, is truncated
// or corrupt, or was written by an unknown format version. Blocks keep their slots, so a Mapper
// constructed from the result continues the build exactly.
BgkMap read_native_map(const std::filesystem::path& file);

}  // namespace bgkmap
