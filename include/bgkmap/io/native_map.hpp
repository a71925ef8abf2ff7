// The native .bgk map file: alpha/beta of every touched block and every parameter, so that a
// build can be resumed, queried and evaluated. Part of the core library (bgkmap::core); the
// layout is documented in docs/FORMAT.md.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "bgkmap/io/held_inputs.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// The .bgk format version this build writes. It reads this one and versions 1 and 2 (every cell
// of every block; version 1 without the held inputs: a version-1 map holds no recorded input).
inline constexpr uint32_t kNativeMapFormatVersion = 3;
// A map with forgetting: version 3's layout, its header naming the half-life, the map's time and
// each block's (so older readers refuse it rather than read its cells undecayed).
inline constexpr uint32_t kForgettingMapFormatVersion = 4;

// Writes atomically (temporary file, then rename). Write failures throw std::runtime_error naming
// the file; an existing file is then left as it was. `held`: the scans the map holds (a build's
// checkpoints and outputs record them for --resume). `method`: the method that built the map, recorded
// when not bgkl (bgk and counting maps are BgkMaps too, but --resume must not continue them as BGK-L).
void write_native_map(const std::filesystem::path& file, const BgkMap& map, const std::vector<HeldInput>& held = {},
                      const std::string& method = "bgkl");

// The pieces of a .bgk, for writers that put the block records in place themselves (the ranks of
// a distributed build each write their own blocks into the one file); write_native_map writes
// exactly these. The bytes before the records, `record_bytes` being the records' total length
// (throws std::runtime_error when the header would exceed its limit):
// `forgetting`: the map's (forgetting() of a BgkMap); a map with it on is written as version 4.
std::string native_map_head(const BuildParams& params, int cells_per_block, uint64_t block_count, uint64_t record_bytes,
                            const std::vector<HeldInput>& held, const std::string& method = "bgkl",
                            const Forgetting& forgetting = Forgetting{});
// Appends the record of the block in `slot` to `out` (records vary in length); returns its length.
size_t append_native_map_record(std::string& out, const BgkMap& map, uint32_t slot);
// The file's CRC-32 (zlib's) of some bytes, e.g. one record.
uint32_t native_map_crc(const char* bytes, size_t n);
// The CRC-32 of records laid end to end, from each record's own CRC-32 and length.
uint32_t native_map_records_crc(const std::vector<uint32_t>& record_crcs, const std::vector<uint64_t>& record_bytes);
// The bytes after the records.
std::string native_map_tail(uint32_t records_crc);

// A map with forgetting as a read sees it (every block decayed to the map's time), or as stored
// (each block at its own time: what a Mapper continuing the build needs to stay exact).
enum class StoredTime { kDecayToNow, kAsStored };

// Reads a native .bgk map; throws InputError naming the file when it is not one, is truncated
// or corrupt, or was written by an unknown format version. Blocks keep their slots, so a Mapper
// constructed from the result (read kAsStored) continues the build exactly.
BgkMap read_native_map(const std::filesystem::path& file);

// The same with what the header records beside the map.
struct NativeMapFile {
  BgkMap map;
  std::vector<HeldInput> held;  // empty for version 1
  uint32_t version = 0;
  std::string method = "bgkl";  // the header's "method", bgkl when it has none
};
NativeMapFile read_native_map_file(const std::filesystem::path& file, StoredTime time = StoredTime::kDecayToNow);

}  // namespace bgkmap
