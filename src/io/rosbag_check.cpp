#include "rosbag_check.hpp"

#include <bzlib.h>
#include <roslz4/lz4s.h>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <set>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/io/errors.hpp"
#include "text_lines.hpp"

namespace bgkmap::io_detail {

namespace {

// Record ops of format 2.0.
constexpr uint8_t kMessageData = 0x02, kBagHeader = 0x03, kIndexData = 0x04, kChunk = 0x05, kChunkInfo = 0x06,
                  kConnection = 0x07;
constexpr uint32_t kMaxHeaderBytes = 1u << 20;  // record headers are a few fields of names and numbers

using Fields = std::map<std::string, std::string>;

struct Record {
  uint64_t pos = 0;  // of its header length
  uint8_t op = 0;
  Fields fields;
  uint64_t data_pos = 0;
  uint32_t data_len = 0;
};

uint32_t u32_at(const char* p) {
  uint32_t v;
  std::memcpy(&v, p, 4);
  return v;
}

class BagWalk {
 public:
  explicit BagWalk(const std::filesystem::path& file) : file_(file), in_(file, std::ios::binary) {
    std::error_code ec;
    size_ = std::filesystem::file_size(file, ec);
    if (!in_ || ec) throw InputError(file, "cannot open for reading");
  }

  [[noreturn]] void fail(uint64_t pos, const std::string& what) const {
    throw InputError(file_, "corrupt ROS bag at byte " + std::to_string(pos) + ": " + what);
  }

  uint64_t size() const { return size_; }
  const std::filesystem::path& file() const { return file_; }

  std::string read(uint64_t pos, uint64_t n) {
    std::string bytes(n, '\0');
    in_.seekg(static_cast<std::streamoff>(pos));
    if (!in_.read(bytes.data(), static_cast<std::streamsize>(n))) fail(pos, "cannot read " + std::to_string(n) + " bytes");
    return bytes;
  }

  // Parses "len name=value" fields; false when they do not tile the header exactly.
  static bool parse_fields(const char* p, uint64_t n, Fields& fields) {
    while (n > 0) {
      if (n < 4) return false;
      const uint32_t len = u32_at(p);
      if (len > n - 4) return false;
      const char* field = p + 4;
      const char* eq = static_cast<const char*>(std::memchr(field, '=', len));
      if (!eq) return false;
      fields[std::string(field, eq)] = std::string(eq + 1, field + len);
      p += 4 + uint64_t(len);
      n -= 4 + uint64_t(len);
    }
    return true;
  }

  // The record at `pos` of a buffer `bytes` of `limit` bytes (a chunk's data; or, without
  // `data_inside`, a record's header and data length read from the file).
  static bool parse_record(const char* bytes, uint64_t limit, uint64_t pos, Record& r, bool data_inside = true) {
    if (pos > limit || limit - pos < 4) return false;
    const uint32_t header_len = u32_at(bytes + pos);
    if (header_len > kMaxHeaderBytes || limit - pos - 4 < uint64_t(header_len) + 4) return false;
    r = Record{};
    r.pos = pos;
    if (!parse_fields(bytes + pos + 4, header_len, r.fields)) return false;
    const auto op = r.fields.find("op");
    if (op == r.fields.end() || op->second.size() != 1) return false;
    r.op = static_cast<uint8_t>(op->second[0]);
    r.data_pos = pos + 4 + header_len + 4;
    r.data_len = u32_at(bytes + pos + 4 + header_len);
    return !data_inside || r.data_len <= limit - r.data_pos;
  }

  // The next record of the file at `pos` (its header read; its data left on disk).
  Record record_at(uint64_t pos) {
    if (size_ - pos < 4) fail(pos, "a record cut short");
    const uint32_t header_len = u32_at(read(pos, 4).data());
    if (header_len > kMaxHeaderBytes || size_ - pos - 4 < uint64_t(header_len) + 4)
      fail(pos, "a record header of " + std::to_string(header_len) + " bytes runs past the end of the file");
    const std::string head = read(pos, 4 + uint64_t(header_len) + 4);
    Record r;
    if (!parse_record(head.data(), head.size(), 0, r, false)) fail(pos, "a malformed record header");
    r.pos = pos;
    r.data_pos += pos;
    if (r.data_len > size_ - r.data_pos) fail(pos, "record data of " + std::to_string(r.data_len) + " bytes runs past the end of the file");
    return r;
  }

  template <typename T>
  T field(const Record& r, const char* name) const {
    const auto f = r.fields.find(name);
    if (f == r.fields.end() || f->second.size() != sizeof(T)) fail(r.pos, std::string("no field '") + name + "' of " + std::to_string(sizeof(T)) + " bytes");
    T v;
    std::memcpy(&v, f->second.data(), sizeof(T));
    return v;
  }

 private:
  std::filesystem::path file_;
  std::ifstream in_;
  uint64_t size_ = 0;
};

// A chunk's records, decompressed: the offsets an index entry may name (a message record, or
// connection records leading to one, which rosbag_storage steps over).
std::set<uint32_t> message_offsets(BagWalk& walk, const Record& chunk) {
  const std::string compression = chunk.fields.count("compression") ? chunk.fields.at("compression") : "";
  const uint32_t size = walk.field<uint32_t>(chunk, "size");
  require_memory(double(chunk.data_len) + double(size),
                 "a chunk of " + walk.file().string() + " (" + format_bytes(size) + " of messages)", "give a larger --max-memory");
  std::string packed = walk.read(chunk.data_pos, chunk.data_len);
  std::string data;
  if (compression == "none") {
    if (packed.size() != size) walk.fail(chunk.pos, "an uncompressed chunk whose size disagrees with its data");
    data.swap(packed);
  } else if (compression == "bz2" || compression == "lz4") {
    data.assign(size, '\0');
    unsigned int out = size;
    const bool ok = compression == "bz2"
                        ? BZ2_bzBuffToBuffDecompress(data.data(), &out, packed.data(), chunk.data_len, 0, 0) == BZ_OK
                        : roslz4_buffToBuffDecompress(packed.data(), chunk.data_len, data.data(), &out) == ROSLZ4_OK;
    if (!ok || out != size) walk.fail(chunk.pos, "a " + compression + " chunk that does not decompress to its size");
  } else {
    walk.fail(chunk.pos, "a chunk compressed by '" + excerpt(compression.substr(0, 16)) + "' (none, bz2 and lz4 are read)");
  }
  std::vector<Record> records;
  for (uint64_t pos = 0; pos < data.size();) {
    Record r;
    if (!BagWalk::parse_record(data.data(), data.size(), pos, r) || (r.op != kMessageData && r.op != kConnection))
      walk.fail(chunk.pos, "a malformed record at offset " + std::to_string(pos) + " of its chunk");
    const auto sized = [&](const char* name, size_t bytes) { return r.fields.count(name) && r.fields.at(name).size() == bytes; };
    if (r.op == kMessageData && !(sized("conn", 4) && sized("time", 8)))
      walk.fail(chunk.pos, "a message record without conn and time at offset " + std::to_string(pos) + " of its chunk");
    Fields connection;
    if (r.op == kConnection && !BagWalk::parse_fields(data.data() + r.data_pos, r.data_len, connection))
      walk.fail(chunk.pos, "a connection record whose connection header is malformed at offset " + std::to_string(pos) +
                               " of its chunk");
    records.push_back(r);
    pos = r.data_pos + r.data_len;
  }
  std::set<uint32_t> offsets;
  bool leads_to_message = false;
  for (auto r = records.rbegin(); r != records.rend(); ++r) {
    leads_to_message = r->op == kMessageData || leads_to_message;
    if (leads_to_message) offsets.insert(static_cast<uint32_t>(r->pos));
  }
  return offsets;
}

}  // namespace

std::map<std::string, uint64_t> check_rosbag_structure(const std::filesystem::path& bag) {
  BagWalk walk(bag);
  constexpr char kVersion[] = "#ROSBAG V2.0\n";
  constexpr uint64_t kVersionBytes = sizeof kVersion - 1;
  if (walk.size() < kVersionBytes || walk.read(0, kVersionBytes) != kVersion)
    throw InputError(bag, "not a ROS 1 bag of format 2.0 (no '#ROSBAG V2.0' line)");
  const Record header = walk.record_at(kVersionBytes);
  if (header.op != kBagHeader) walk.fail(header.pos, "no bag header record");
  const uint64_t index_pos = walk.field<uint64_t>(header, "index_pos");
  const uint32_t conn_count = walk.field<uint32_t>(header, "conn_count"), chunk_count = walk.field<uint32_t>(header, "chunk_count");
  if (index_pos == 0) throw InputError(bag, "an unindexed ROS bag (its recording was cut off; 'rosbag reindex' repairs it)");

  std::map<uint64_t, std::set<uint32_t>> chunks;       // chunk position -> its message offsets
  std::map<uint64_t, uint32_t> indexes_after;           // chunk position -> index records after it
  std::map<uint32_t, uint64_t> index_counts;            // connection -> messages indexed
  std::map<uint32_t, std::string> topics;               // connection -> topic (from the index section)
  std::vector<Record> chunk_infos;
  uint64_t chunk = 0;
  bool index_seen = false;
  uint32_t connections = 0;
  for (uint64_t pos = header.data_pos + header.data_len; pos < walk.size();) {
    const Record r = walk.record_at(pos);
    if (pos == index_pos) index_seen = true;
    if (r.op == kChunk) {
      if (index_seen) walk.fail(pos, "a chunk after the index");
      chunk = pos;
      chunks[pos] = message_offsets(walk, r);
      indexes_after[pos] = 0;
    } else if (r.op == kIndexData) {
      if (chunks.empty() || index_seen) walk.fail(pos, "an index record outside the chunks");
      const uint32_t conn = walk.field<uint32_t>(r, "conn"), count = walk.field<uint32_t>(r, "count");
      if (walk.field<uint32_t>(r, "ver") != 1 || uint64_t(count) * 12 != r.data_len)
        walk.fail(pos, "an index record whose count disagrees with its data");
      const std::string entries = walk.read(r.data_pos, r.data_len);
      for (uint32_t i = 0; i < count; ++i)
        if (!chunks[chunk].count(u32_at(entries.data() + 12 * size_t(i) + 8)))
          walk.fail(pos, "an index entry that points at no message of its chunk");
      ++indexes_after[chunk];
      index_counts[conn] += count;
    } else if (r.op == kConnection) {
      if (!index_seen) walk.fail(pos, "a connection record outside the index");
      // rosbag_storage parses the connection header (topic, type, md5sum) unchecked: it read past its buffer.
      const std::string data = walk.read(r.data_pos, r.data_len);
      Fields connection;
      if (!BagWalk::parse_fields(data.data(), data.size(), connection))
        walk.fail(pos, "a connection record whose connection header is malformed");
      topics[walk.field<uint32_t>(r, "conn")] = r.fields.count("topic") ? r.fields.at("topic") : "";
      ++connections;
    } else if (r.op == kChunkInfo) {
      if (!index_seen) walk.fail(pos, "a chunk info record outside the index");
      chunk_infos.push_back(r);
    } else {
      walk.fail(pos, "a record of unknown op " + std::to_string(r.op));
    }
    pos = r.data_pos + r.data_len;
  }
  if (!index_seen) walk.fail(index_pos, "the bag header's index position is no record");
  if (connections != conn_count || chunk_infos.size() != chunk_count)
    walk.fail(index_pos, "the index holds " + std::to_string(connections) + " connections and " +
                             std::to_string(chunk_infos.size()) + " chunk infos, the bag header says " +
                             std::to_string(conn_count) + " and " + std::to_string(chunk_count));
  for (const Record& info : chunk_infos) {
    const uint64_t at = walk.field<uint64_t>(info, "chunk_pos");
    const uint32_t count = walk.field<uint32_t>(info, "count");
    walk.field<uint64_t>(info, "start_time");
    walk.field<uint64_t>(info, "end_time");
    if (walk.field<uint32_t>(info, "ver") != 1 || uint64_t(count) * 8 != info.data_len || !chunks.count(at) ||
        indexes_after[at] < count)
      walk.fail(info.pos, "a chunk info record that disagrees with its chunk");
    const std::string entries = walk.read(info.data_pos, info.data_len);
    for (uint32_t i = 0; i < count; ++i)
      if (!topics.count(u32_at(entries.data() + 8 * size_t(i)))) walk.fail(info.pos, "a chunk info naming an unknown connection");
  }
  std::map<std::string, uint64_t> messages;
  for (const auto& [conn, count] : index_counts) {
    if (!topics.count(conn)) walk.fail(index_pos, "messages of connection " + std::to_string(conn) + ", which is not declared");
    messages[topics[conn]] += count;
  }
  return messages;
}

}  // namespace bgkmap::io_detail
