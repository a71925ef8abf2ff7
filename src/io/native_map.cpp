// The native .bgk map file: every parameter and every block's alpha/beta, bit-exact, so that a
// build can be resumed or evaluated later. Its layout, versions 1 to 3 byte by byte, is in
// docs/FORMAT.md. This build writes version 3: each block record is its key and only the values
// that moved from the prior (native_block_codec.hpp); versions 1 and 2 store every cell.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>
#include <zlib.h>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/methods/param_error.hpp"
#include "bgkmap/map/internal/cell_pool.hpp"
#include "input_file.hpp"
#include "native_block_codec.hpp"

namespace bgkmap {

namespace {

constexpr char kMagic[8] = {'\x89', 'B', 'G', 'K', '\r', '\n', '\x1a', '\n'};
constexpr char kEndMarker[8] = {'B', 'G', 'K', ':', 'E', 'N', 'D', '\n'};
constexpr uint64_t kPrefixBytes = 16;         // magic, version, H
constexpr uint64_t kHeaderTailBytesV2 = 16;   // C, B, header CRC
constexpr uint64_t kHeaderTailBytes = 24;     // C, B, D (the records' bytes), header CRC
constexpr uint64_t kRecordHeadBytes = 16;     // a version-3 record's key and body length
constexpr uint64_t kTrailerBytes = 4 + sizeof(kEndMarker);
// A few hundred bytes of parameters and about 150 bytes per held input file; the length is checked
// against the file's size before anything is allocated.
constexpr uint32_t kMaxJsonHeaderBytesV1 = 1u << 20;
constexpr uint32_t kMaxJsonHeaderBytes = 64u << 20;

// zlib's CRC-32: its tables and word-at-a-time loop keep checksums cheap beside writing and reading large maps.
class Crc32 {
 public:
  void update(const char* data, size_t n) { state_ = crc32_z(state_, reinterpret_cast<const Bytef*>(data), n); }
  void update(const std::string& bytes) { update(bytes.data(), bytes.size()); }
  uint32_t value() const { return static_cast<uint32_t>(state_); }

 private:
  uLong state_ = crc32_z(0, nullptr, 0);
};

// A block's cells as versions 1 and 2 store them (each f32 alpha, f32 beta, little-endian): on a
// little-endian host exactly the bytes of Cell, copied at once.
static_assert(sizeof(Cell) == 8 && offsetof(Cell, alpha) == 0 && offsetof(Cell, beta) == 4,
              "Cell is the file's 8-byte cell record");
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
constexpr bool kCellsAreFileBytes = true;
#else
constexpr bool kCellsAreFileBytes = false;
#endif

// Explicit little-endian encoding, whatever the host's byte order.
void put_u32(std::string& out, uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
}
void put_u64(std::string& out, uint64_t v) {
  for (int i = 0; i < 8; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
}
void put_i32(std::string& out, int32_t v) { put_u32(out, static_cast<uint32_t>(v)); }

uint32_t get_u32(const char* p) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(static_cast<uint8_t>(p[i])) << (8 * i);
  return v;
}
uint64_t get_u64(const char* p) {
  uint64_t v = 0;
  for (int i = 0; i < 8; ++i) v |= static_cast<uint64_t>(static_cast<uint8_t>(p[i])) << (8 * i);
  return v;
}
int32_t get_i32(const char* p) { return static_cast<int32_t>(get_u32(p)); }
float get_f32(const char* p) {
  const uint32_t bits = get_u32(p);
  float v;
  std::memcpy(&v, &bits, sizeof v);
  return v;
}

uint64_t block_record_bytes(uint64_t cells_per_block) { return 12 + 8 * cells_per_block; }

std::string hex32(uint32_t v) {
  static const char digits[] = "0123456789abcdef";
  std::string s = "0x";
  for (int i = 7; i >= 0; --i) s.push_back(digits[(v >> (4 * i)) & 0xFu]);
  return s;
}

// Keys whose cells' int32 indices would overflow cannot come from a real map.
bool block_key_in_range(const BlockKey& key, int n) {
  const auto fits = [n](int32_t k) {
    const int64_t first = static_cast<int64_t>(k) * n;
    return first >= std::numeric_limits<int32_t>::min() && first + n - 1 <= std::numeric_limits<int32_t>::max();
  };
  return fits(key.x) && fits(key.y) && fits(key.z);
}

bool valid_count(float v) { return std::isfinite(v) && v > 0.0f; }

std::string key_string(const BlockKey& k) {
  return "(" + std::to_string(k.x) + ", " + std::to_string(k.y) + ", " + std::to_string(k.z) + ")";
}

// Reads exactly n bytes or throws "truncated"; the file size was checked up front, so this only
// fires when the file shrinks while being read.
void read_exact(std::istream& in, char* out, size_t n, const std::filesystem::path& file) {
  in.read(out, static_cast<std::streamsize>(n));
  if (static_cast<size_t>(in.gcount()) != n) throw InputError(file, "truncated .bgk map (unexpected end of file)");
}

std::vector<HeldInput> held_from_header(const std::filesystem::path& file, const nlohmann::json& header) {
  const auto inputs = header.find("inputs");
  if (inputs == header.end() || !inputs->is_array()) throw InputError(file, "corrupt .bgk header (no \"inputs\" list)");
  return held_inputs_from_json(file, *inputs, "corrupt .bgk header");
}

struct Header {
  BuildParams params;
  std::vector<HeldInput> held;
  std::string method;
  Forgetting forgetting;  // version 4: half-life, time and per-block times (checked against B later)
};

nlohmann::json forgetting_to_json(const Forgetting& f) {
  return {{"half_life_scans", f.half_life_scans}, {"time", f.now}, {"block_times", f.block_time}};
}

// Version 4's "forget": a half-life the command line takes, and block times no later than the map's.
Forgetting forgetting_from_header(const std::filesystem::path& file, const nlohmann::json& header) {
  const auto bad = [&](const std::string& what) { return InputError(file, "corrupt .bgk header (\"forget\": " + what + ")"); };
  const auto f = header.find("forget");
  if (f == header.end() || !f->is_object()) throw bad("missing in a version-4 map");
  const auto h = f->find("half_life_scans"), t = f->find("time"), b = f->find("block_times");
  if (h == f->end() || !h->is_number() || !(h->get<double>() > 0) || !(h->get<double>() <= 1e9))
    throw bad("half_life_scans must be in (0, 1e9] scans");
  if (t == f->end() || !t->is_number_unsigned()) throw bad("time must be a whole number of scans");
  if (b == f->end() || !b->is_array()) throw bad("no block_times list");
  Forgetting out;
  out.half_life_scans = h->get<double>();
  out.now = t->get<uint64_t>();
  out.block_time.reserve(b->size());
  for (const nlohmann::json& v : *b) {
    if (!v.is_number_unsigned() || v.get<uint64_t>() > out.now) throw bad("a block time is not a scan up to the map's time");
    out.block_time.push_back(v.get<uint64_t>());
  }
  return out;
}

Header parse_header(const std::filesystem::path& file, const std::string& json_text, uint32_t version) {
  const nlohmann::json header = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (header.is_discarded() || !header.is_object()) throw InputError(file, "corrupt .bgk header (not a JSON object)");
  const auto params_json = header.find("params");
  if (params_json == header.end()) throw InputError(file, "corrupt .bgk header (no \"params\")");
  Header out{BuildParams{}, {}, "bgkl", {}};
  const auto method = header.find("method");
  if (method != header.end()) {
    if (!method->is_string() || method->get<std::string>().empty())
      throw InputError(file, "corrupt .bgk header (\"method\" is not a name)");
    out.method = method->get<std::string>();
  }
  try {
    out.params = params_from_json(*params_json);
    if (out.method == "counting") out.params.validate();  // counts by rays: --ell reaches nothing
    else out.params.check_kernel_reach();
  } catch (const ParamError& e) {  // named by the header's keys
    throw InputError(file, "bad parameters in .bgk header: " + e.as_keywords());
  } catch (const std::invalid_argument& e) {
    throw InputError(file, std::string("bad parameters in .bgk header: ") + e.what());
  }
  if (version >= 2) out.held = held_from_header(file, header);
  if (version >= 4) out.forgetting = forgetting_from_header(file, header);
  return out;
}


// Versions 1 and 2: the file holds exactly B records of 12 + 8 * C bytes.
void check_whole_block_sizes(const std::filesystem::path& file, uint64_t data_bytes, uint64_t block_count,
                             uint32_t cells_per_block) {
  const uint64_t record_bytes = block_record_bytes(cells_per_block);
  if (block_count > data_bytes / record_bytes)
    throw InputError(file, "truncated .bgk map (header promises " + std::to_string(block_count) + " blocks of " +
                               std::to_string(record_bytes) + " bytes; file has " + std::to_string(data_bytes) +
                               " bytes of block data)");
  if (block_count * record_bytes != data_bytes)
    throw InputError(file, "corrupt .bgk map (file is " + std::to_string(data_bytes - block_count * record_bytes) +
                               " bytes longer than its " + std::to_string(block_count) + " blocks need)");
  if (block_count > std::numeric_limits<uint32_t>::max())
    throw InputError(file, "corrupt .bgk header (block count " + std::to_string(block_count) + " exceeds 2^32)");
}

// Version 3: the file holds the header's D bytes of records, room for B of them; the B blocks
// unpacked must fit --max-memory (a block's record can be 1/128 of its cells' bytes).
void check_sparse_sizes(const std::filesystem::path& file, uint64_t data_bytes, uint64_t record_bytes,
                          uint64_t block_count, uint32_t cells_per_block) {
  if (record_bytes > data_bytes)
    throw InputError(file, "truncated .bgk map (header promises " + std::to_string(record_bytes) +
                               " bytes of block records; file has " + std::to_string(data_bytes) + ")");
  if (record_bytes != data_bytes)
    throw InputError(file, "corrupt .bgk map (file is " + std::to_string(data_bytes - record_bytes) +
                               " bytes longer than its " + std::to_string(block_count) + " blocks need)");
  if (block_count > record_bytes / (kRecordHeadBytes + io_detail::min_block_body_bytes(cells_per_block)))
    throw InputError(file, "corrupt .bgk header (" + std::to_string(block_count) + " blocks cannot fit in " +
                               std::to_string(record_bytes) + " bytes of records)");
  if (block_count > std::numeric_limits<uint32_t>::max())
    throw InputError(file, "corrupt .bgk header (block count " + std::to_string(block_count) + " exceeds 2^32)");
  io_detail::require_read_memory(file, block_count, double(sizeof(Cell)) * cells_per_block, "blocks");
}

// What the block records of a file gave: their CRC-32 and the first content error, reported only
// after the checksum passed (a flipped bit should read as "corrupt", not as whatever nonsense
// value it produced).
struct RecordsRead {
  uint32_t crc = 0;
  std::string content_error;
};

// The slot of block b's key, or "" set to what is wrong with the key.
uint32_t place_block(BgkMap& map, uint64_t b, const BlockKey& key, std::string& error) {
  if (!block_key_in_range(key, map.params().grid.cells_per_side())) {
    error = "block " + std::to_string(b) + " has an out-of-range key " + key_string(key);
    return 0;
  }
  const uint32_t slot = map.ensure_slot(key);
  if (slot != b) error = "block " + std::to_string(b) + " repeats key " + key_string(key);
  return slot;
}

std::string invalid_cell(const Cell* cells, uint32_t cells_per_block, uint64_t b) {
  for (uint32_t i = 0; i < cells_per_block; ++i)
    if (!valid_count(cells[i].alpha) || !valid_count(cells[i].beta))
      return "block " + std::to_string(b) + " cell " + std::to_string(i) + " has a non-positive or non-finite alpha/beta";
  return "";
}

// Versions 1 and 2: B records of 12 + 8 * C bytes (sizes checked against the file already).
RecordsRead read_whole_blocks(std::istream& in, const std::filesystem::path& file, BgkMap& map, uint64_t block_count,
                              uint32_t cells_per_block) {
  RecordsRead out;
  Crc32 data_crc;
  std::string record(block_record_bytes(cells_per_block), '\0');
  for (uint64_t b = 0; b < block_count; ++b) {
    read_exact(in, record.data(), record.size(), file);
    data_crc.update(record);
    if (!out.content_error.empty()) continue;
    const BlockKey key{get_i32(record.data()), get_i32(record.data() + 4), get_i32(record.data() + 8)};
    const uint32_t slot = place_block(map, b, key, out.content_error);
    if (!out.content_error.empty()) continue;
    Cell* cells = map.block_cells(slot);
    const char* p = record.data() + 12;
    if (kCellsAreFileBytes)
      std::memcpy(static_cast<void*>(cells), p, sizeof(Cell) * cells_per_block);
    else
      for (uint32_t i = 0; i < cells_per_block; ++i) cells[i] = Cell{get_f32(p + 8 * i), get_f32(p + 8 * i + 4)};
    out.content_error = invalid_cell(cells, cells_per_block, b);
  }
  out.crc = data_crc.value();
  return out;
}

// Version 3: B records of key, u32 L and an L-byte body, `data_bytes` in all. A length that does
// not fit ends the walk; the rest of the bytes still go through the checksum.
RecordsRead read_sparse_blocks(std::istream& in, const std::filesystem::path& file, BgkMap& map,
                                 uint64_t block_count, uint32_t cells_per_block, uint64_t data_bytes) {
  RecordsRead out;
  Crc32 data_crc;
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  const uint64_t min_body = io_detail::min_block_body_bytes(cells_per_block);
  const uint64_t max_body = io_detail::max_block_body_bytes(cells_per_block);
  std::string record(kRecordHeadBytes + max_body, '\0');
  uint64_t left = data_bytes;
  for (uint64_t b = 0; b < block_count && out.content_error.empty(); ++b) {
    if (left < kRecordHeadBytes) {
      out.content_error = "block " + std::to_string(b) + " of " + std::to_string(block_count) +
                          " starts past the end of the block data";
      break;
    }
    read_exact(in, record.data(), kRecordHeadBytes, file);
    data_crc.update(record.data(), kRecordHeadBytes);
    left -= kRecordHeadBytes;
    const uint32_t body = get_u32(record.data() + 12);
    if (body < min_body || body > max_body || body > left) {
      out.content_error = "block " + std::to_string(b) + " claims " + std::to_string(body) + " bytes of cells (" +
                          std::to_string(min_body) + " to " + std::to_string(std::min(max_body, left)) + ")";
      break;
    }
    read_exact(in, record.data() + kRecordHeadBytes, body, file);
    data_crc.update(record.data() + kRecordHeadBytes, body);
    left -= body;
    const BlockKey key{get_i32(record.data()), get_i32(record.data() + 4), get_i32(record.data() + 8)};
    const uint32_t slot = place_block(map, b, key, out.content_error);
    if (!out.content_error.empty()) break;
    Cell* cells = map.block_cells(slot);
    const std::string bad =
        io_detail::decode_block_body(record.data() + kRecordHeadBytes, body, cells, cells_per_block, prior);
    out.content_error = bad.empty() ? invalid_cell(cells, cells_per_block, b) : "block " + std::to_string(b) + ": " + bad;
  }
  if (out.content_error.empty() && left != 0)
    out.content_error = std::to_string(left) + " bytes follow the last block's record";
  for (std::string chunk(std::min<uint64_t>(left, 1u << 16), '\0'); left > 0;) {
    const size_t n = static_cast<size_t>(std::min<uint64_t>(left, chunk.size()));
    read_exact(in, chunk.data(), n, file);
    data_crc.update(chunk.data(), n);
    left -= n;
  }
  out.crc = data_crc.value();
  return out;
}


}  // namespace

std::string native_map_head(const BuildParams& params, int cells_per_block, uint64_t block_count, uint64_t record_bytes,
                            const std::vector<HeldInput>& held, const std::string& method, const Forgetting& forgetting) {
  nlohmann::json head{{"params", params_to_json(params)}, {"inputs", held_inputs_to_json(held)}};
  if (method != "bgkl") head["method"] = method;  // bgkl maps' bytes stay as they were
  if (forgetting.on()) head["forget"] = forgetting_to_json(forgetting);
  const std::string json = head.dump();
  if (json.size() > kMaxJsonHeaderBytes)
    throw std::runtime_error("the .bgk header would exceed 64 MiB (" + std::to_string(held.size()) + " held input files)");
  std::string header(kMagic, sizeof kMagic);
  put_u32(header, forgetting.on() ? kForgettingMapFormatVersion : kNativeMapFormatVersion);
  put_u32(header, static_cast<uint32_t>(json.size()));
  header += json;
  put_u32(header, static_cast<uint32_t>(cells_per_block));
  put_u64(header, block_count);
  put_u64(header, record_bytes);
  Crc32 header_crc;
  header_crc.update(header);
  put_u32(header, header_crc.value());
  return header;
}

size_t append_native_map_record(std::string& out, const BgkMap& map, uint32_t slot) {
  const size_t at = out.size();
  const BlockKey& key = map.key_of_slot(slot);
  put_i32(out, key.x);
  put_i32(out, key.y);
  put_i32(out, key.z);
  put_u32(out, 0);  // the body's length, known once it is written
  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  const size_t body = io_detail::append_block_body(out, map.block_cells(slot), size_t(map.cells_per_block()), prior);
  for (int i = 0; i < 4; ++i) out[at + 12 + i] = static_cast<char>((body >> (8 * i)) & 0xFFu);
  return out.size() - at;
}

uint32_t native_map_crc(const char* bytes, size_t n) {
  Crc32 crc;
  crc.update(bytes, n);
  return crc.value();
}

uint32_t native_map_records_crc(const std::vector<uint32_t>& record_crcs, const std::vector<uint64_t>& record_bytes) {
  uLong crc = crc32_z(0, nullptr, 0);
  for (size_t i = 0; i < record_crcs.size(); ++i)
    crc = crc32_combine64(crc, record_crcs[i], static_cast<z_off64_t>(record_bytes.at(i)));
  return static_cast<uint32_t>(crc);
}

std::string native_map_tail(uint32_t records_crc) {
  std::string trailer;
  put_u32(trailer, records_crc);
  trailer.append(kEndMarker, sizeof kEndMarker);
  return trailer;
}

// Two passes over the blocks: the header holds the records' length, and holding the records
// themselves would take memory in proportion to the map.
void write_native_map(const std::filesystem::path& file, const BgkMap& map, const std::vector<HeldInput>& held,
                      const std::string& method) {
  std::string record;
  uint64_t records_bytes = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    record.clear();
    records_bytes += append_native_map_record(record, map, slot);
  }
  std::string header;
  try {
    header = native_map_head(map.params(), map.cells_per_block(), map.block_count(), records_bytes, held, method,
                             map.forgetting());
  } catch (const std::runtime_error& e) {
    throw std::runtime_error(file.string() + ": " + e.what());
  }
  write_file_atomically(file, [&](std::ostream& out) {
    out.write(header.data(), static_cast<std::streamsize>(header.size()));
    Crc32 data_crc;
    for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
      record.clear();
      append_native_map_record(record, map, slot);
      data_crc.update(record);
      out.write(record.data(), static_cast<std::streamsize>(record.size()));
    }
    const std::string trailer = native_map_tail(data_crc.value());
    out.write(trailer.data(), static_cast<std::streamsize>(trailer.size()));
  });
}

BgkMap read_native_map(const std::filesystem::path& file) { return read_native_map_file(file).map; }

NativeMapFile read_native_map_file(const std::filesystem::path& file, StoredTime time) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (!fs::exists(status)) throw InputError(file, "no such file");
  if (!fs::is_regular_file(status)) throw InputError(file, "not a regular file");
  const uint64_t file_size = fs::file_size(file, ec);
  if (ec) throw InputError(file, "cannot read its size (" + ec.message() + ")");
  if (file_size == 0) throw InputError(file, "empty file (not a .bgk map)");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open for reading");

  // Magic first, on whatever prefix there is: a short foreign file is "not a map", not "truncated".
  std::string head(static_cast<size_t>(std::min<uint64_t>(file_size, kPrefixBytes)), '\0');
  read_exact(in, head.data(), head.size(), file);
  const size_t magic_bytes = std::min(head.size(), sizeof kMagic);
  if (std::memcmp(head.data(), kMagic, magic_bytes) != 0) {
    if (head.rfind("# Octomap", 0) == 0) throw InputError(file, "an OctoMap file, not a native .bgk map (bad magic)");
    throw InputError(file, "not a native .bgk map (bad magic)");
  }
  if (file_size < kPrefixBytes)
    throw InputError(file, "truncated .bgk map (" + std::to_string(file_size) + " bytes; even an empty map has " +
                               std::to_string(kPrefixBytes + kHeaderTailBytesV2 + kTrailerBytes) + ")");
  const uint32_t version = get_u32(head.data() + 8);
  if (version < 1 || version > kForgettingMapFormatVersion)
    throw InputError(file, "unsupported .bgk format version " + std::to_string(version) + " (this build reads versions 1 to " +
                               std::to_string(kForgettingMapFormatVersion) + ")");
  const uint64_t tail_bytes = version >= 3 ? kHeaderTailBytes : kHeaderTailBytesV2;
  const uint64_t min_size = kPrefixBytes + tail_bytes + kTrailerBytes;
  const uint32_t json_bytes = get_u32(head.data() + 12);
  const uint32_t max_json_bytes = version == 1 ? kMaxJsonHeaderBytesV1 : kMaxJsonHeaderBytes;
  if (json_bytes > max_json_bytes)
    throw InputError(file, "corrupt .bgk header (JSON header length " + std::to_string(json_bytes) + " exceeds " +
                               (version == 1 ? "1" : "64") + " MiB)");
  if (file_size < min_size + json_bytes)
    throw InputError(file, "truncated .bgk map (" + std::to_string(file_size) + " bytes; its header alone needs " +
                               std::to_string(min_size + json_bytes) + ")");

  // The rest of the header, checked against its CRC before any field of it is trusted.
  std::string rest(json_bytes + tail_bytes, '\0');
  read_exact(in, rest.data(), rest.size(), file);
  const char* tail = rest.data() + json_bytes;
  Crc32 header_crc;
  header_crc.update(head);
  header_crc.update(rest.data(), rest.size() - 4);
  const uint32_t stored_header_crc = get_u32(rest.data() + rest.size() - 4);
  if (header_crc.value() != stored_header_crc)
    throw InputError(file, "corrupt .bgk header (checksum mismatch: stored " + hex32(stored_header_crc) + ", computed " +
                               hex32(header_crc.value()) + ")");

  Header parsed = parse_header(file, rest.substr(0, json_bytes), version);
  const BuildParams& params = parsed.params;
  const uint32_t cells_per_block = get_u32(tail);
  const uint64_t block_count = get_u64(tail + 4);
  if (cells_per_block != static_cast<uint32_t>(params.grid.cells_per_block()))
    throw InputError(file, "corrupt .bgk header (" + std::to_string(cells_per_block) + " cells per block, but block depth " +
                               std::to_string(params.grid.block_depth) + " has " +
                               std::to_string(params.grid.cells_per_block()) + ")");

  // Sizes against the file before allocating anything for the blocks.
  const uint64_t data_bytes = file_size - (min_size + json_bytes);
  if (version >= 3)
    check_sparse_sizes(file, data_bytes, get_u64(tail + 12), block_count, cells_per_block);
  else
    check_whole_block_sizes(file, data_bytes, block_count, cells_per_block);

  if (parsed.forgetting.on() && parsed.forgetting.block_time.size() != block_count)
    throw InputError(file, "corrupt .bgk header (\"forget\" gives " + std::to_string(parsed.forgetting.block_time.size()) +
                               " block times for " + std::to_string(block_count) + " blocks)");
  BgkMap map(params);
  if (parsed.forgetting.on()) map.set_forget_half_life(parsed.forgetting.half_life_scans);
  const RecordsRead records = version >= 3
                                  ? read_sparse_blocks(in, file, map, block_count, cells_per_block, data_bytes)
                                  : read_whole_blocks(in, file, map, block_count, cells_per_block);
  char trailer[kTrailerBytes];
  read_exact(in, trailer, sizeof trailer, file);
  const uint32_t stored_data_crc = get_u32(trailer);
  if (std::memcmp(trailer + 4, kEndMarker, sizeof kEndMarker) != 0)
    throw InputError(file, "corrupt .bgk map (end marker missing)");
  if (records.crc != stored_data_crc)
    throw InputError(file, "corrupt .bgk map (block data checksum mismatch: stored " + hex32(stored_data_crc) +
                               ", computed " + hex32(records.crc) + ")");
  if (!records.content_error.empty()) throw InputError(file, "corrupt .bgk map (" + records.content_error + ")");
  if (parsed.forgetting.on()) {
    map.restore_time(parsed.forgetting.now, std::move(parsed.forgetting.block_time));
    if (time == StoredTime::kDecayToNow) map = map.settled();
  }
  return {std::move(map), std::move(parsed.held), version, std::move(parsed.method)};
}

}  // namespace bgkmap
