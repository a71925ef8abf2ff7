// The native .bgk reader. Both CRC-32s are recomputed over the mutated bytes first (where the
// layout puts them), or nearly every mutation would stop at the header checksum; the checks
// behind it (parameters, sizes, keys, cell values) are what a valid-checksum file reaches.
#include <zlib.h>

#include <cstring>
#include <vector>

#include "bgkmap/io/native_map.hpp"
#include "fuzz_support.hpp"

namespace {

uint32_t get_u32(const uint8_t* p) { return uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16 | uint32_t(p[3]) << 24; }
void put_u32(uint8_t* p, uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<uint8_t>(v >> (8 * i));
}

// The offsets are those of docs/FORMAT.md (version 3's header holds the records' length too).
void fix_checksums(std::vector<uint8_t>& bytes) {
  if (bytes.size() < 16) return;
  const uint64_t json_bytes = get_u32(bytes.data() + 12);
  const uint64_t header_crc_at = (get_u32(bytes.data() + 8) >= 3 ? 36 : 28) + json_bytes;
  if (bytes.size() < header_crc_at + 4) return;
  put_u32(bytes.data() + header_crc_at, static_cast<uint32_t>(crc32_z(0, bytes.data(), header_crc_at)));
  const uint64_t data_at = header_crc_at + 4;
  if (bytes.size() < data_at + 12) return;
  const uint64_t data_crc_at = bytes.size() - 12;
  put_u32(bytes.data() + data_crc_at, static_cast<uint32_t>(crc32_z(0, bytes.data() + data_at, data_crc_at - data_at)));
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  std::vector<uint8_t> bytes(data, data + size);
  fix_checksums(bytes);
  const auto file = bgkmap::fuzz::write_input(bytes.data(), bytes.size(), ".bgk");
  bgkmap::fuzz::expect_clean([&] { bgkmap::read_native_map_file(file); });
  return 0;
}
