#include "pcd_header.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>

#include "bgkmap/io/errors.hpp"

namespace bgkmap::pcd {

namespace {

constexpr uint64_t kMaxHeaderBytes = 1 << 20;  // real headers are a few hundred bytes
constexpr uint64_t kMaxPointBytes = 1 << 20;   // far above any descriptor PCL knows
// PCL sizes its buffer and offsets with 32-bit integers.
constexpr uint64_t kMaxDataBytes = std::numeric_limits<uint32_t>::max();
// LZF emits at most 264 bytes per 3-byte back reference (88x); anything beyond is corrupt.
constexpr uint64_t kMaxLzfExpansion = 100;

// Header keywords in the order the PCD spec prescribes.
constexpr std::array<std::string_view, 10> kKeywords = {"VERSION", "FIELDS", "SIZE",      "TYPE",   "COUNT",
                                                        "WIDTH",   "HEIGHT", "VIEWPOINT", "POINTS", "DATA"};
enum Keyword { kVersion, kFields, kSize, kType, kCount, kWidth, kHeight, kViewpoint, kPoints, kData };
// Prefixes PCL's header loop acts on (it matches prefixes, and also accepts COLUMNS for FIELDS).
constexpr std::array<std::string_view, 10> kPclPrefixes = {"FIELDS", "COLUMNS", "SIZE",      "TYPE",   "COUNT",
                                                           "WIDTH",  "HEIGHT",  "VIEWPOINT", "POINTS", "DATA"};

// A token for a message: printable ASCII only, shortened, in quotes.
std::string shown(std::string_view s) {
  std::string out = "'";
  for (size_t i = 0; i < s.size() && i < 32; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    out += (c >= 0x20 && c < 0x7f) ? static_cast<char>(c) : '?';
  }
  if (s.size() > 32) out += "...";
  return out + "'";
}

// PCL splits on spaces, tabs and carriage returns, dropping empty tokens.
std::vector<std::string_view> split_tokens(std::string_view line) {
  std::vector<std::string_view> tokens;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    const size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    if (i > start) tokens.push_back(line.substr(start, i - start));
  }
  return tokens;
}

bool parse_uint(std::string_view s, uint64_t& value) {
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && end == s.data() + s.size();
}

// A leading '+' is allowed, as C++ streams (PCL's parser) allow it.
std::string_view strip_plus(std::string_view s) {
  if (s.size() > 1 && s.front() == '+' && s[1] != '-' && s[1] != '+') s.remove_prefix(1);
  return s;
}

template <typename T>
bool parse_real(std::string_view s, T& value) {
  s = strip_plus(s);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  return ec == std::errc() && end == s.data() + s.size();
}

// Any decimal number, including nan and inf; out-of-range values count (a stream makes them inf).
bool is_number(std::string_view s) {
  s = strip_plus(s);
  double ignored = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), ignored);
  return (ec == std::errc() || ec == std::errc::result_out_of_range) && end == s.data() + s.size();
}

int keyword_index(std::string_view token) {
  const auto it = std::find(kKeywords.begin(), kKeywords.end(), token);
  return it == kKeywords.end() ? -1 : static_cast<int>(it - kKeywords.begin());
}

bool starts_with_pcl_keyword(std::string_view token) {
  return std::any_of(kPclPrefixes.begin(), kPclPrefixes.end(),
                     [&](std::string_view p) { return token.substr(0, p.size()) == p; });
}

class HeaderParser {
 public:
  explicit HeaderParser(const std::filesystem::path& file) : file_(file) {}

  Header parse(const std::string& text, bool whole_file) {
    size_t pos = 0;
    while (pos < text.size() && !seen_[kData]) {
      const size_t newline = text.find('\n', pos);
      if (newline == std::string::npos && !whole_file)
        fail_file("no DATA line in the first " + std::to_string(kMaxHeaderBytes >> 20) + " MiB (not a PCD file?)");
      const size_t end = newline == std::string::npos ? text.size() : newline;
      const std::string_view line = std::string_view(text).substr(pos, end - pos);
      ++line_;
      // An unfinished last line before DATA is a cut-off header, whatever its remains say.
      if (newline == std::string::npos && line.substr(0, 4) != "DATA")
        fail_file("header ends without a DATA line (truncated or not a PCD file)");
      parse_line(line);
      pos = newline == std::string::npos ? text.size() : newline + 1;
    }
    if (!seen_[kData]) {
      if (line_ == 0) fail_file("empty file");
      fail_file("header ends without a DATA line (truncated or not a PCD file)");
    }
    header_.data_offset = pos;
    header_.data_line = line_ + 1;
    reject_keywords_after_data(text, pos);
    check_complete();
    return header_;
  }

 private:
  [[noreturn]] void fail_file(const std::string& what) const { throw InputError(file_, "PCD: " + what); }
  [[noreturn]] void fail(const std::string& what) const {
    throw InputError(file_, "PCD header line " + std::to_string(line_) + ": " + what);
  }

  void parse_line(std::string_view line) {
    if (line.empty()) return;  // PCL skips empty lines, and only those
    const std::vector<std::string_view> tokens = split_tokens(line);
    if (tokens.empty()) fail("blank line of whitespace (PCL would stop reading the header here)");
    if (tokens[0].front() == '#') return;
    const int key = keyword_index(tokens[0]);
    if (key < 0) {
      if (last_ < 0) fail_file("not a PCD file (line " + std::to_string(line_) + " starts with " + shown(tokens[0]) + ")");
      fail("unknown keyword " + shown(tokens[0]));
    }
    if (seen_[key]) fail(std::string(kKeywords[key]) + " appears twice");
    if (key < last_) fail(std::string(kKeywords[key]) + " must come before " + std::string(kKeywords[last_]));
    seen_[key] = true;
    last_ = key;
    const std::vector<std::string_view> values(tokens.begin() + 1, tokens.end());
    switch (key) {
      case kVersion: return;
      case kFields: return parse_fields(values);
      case kSize: return parse_sizes(values);
      case kType: return parse_types(values);
      case kCount: return parse_counts(values);
      case kWidth: header_.width = parse_count(values, "WIDTH"); return;
      case kHeight: header_.height = parse_count(values, "HEIGHT"); return;
      case kViewpoint: return parse_viewpoint(values);
      case kPoints: header_.points = parse_count(values, "POINTS"); return;
      case kData: return parse_data(values);
      default: return;
    }
  }

  void expect_per_field(const std::vector<std::string_view>& values, const char* keyword) const {
    if (!seen_[kFields]) fail(std::string(keyword) + " before FIELDS");
    if (values.size() != header_.fields.size())
      fail(std::string(keyword) + " has " + std::to_string(values.size()) + " values for " +
           std::to_string(header_.fields.size()) + " fields");
  }

  void parse_fields(const std::vector<std::string_view>& values) {
    if (values.empty()) fail("FIELDS names no field");
    for (std::string_view name : values) {
      if (std::any_of(header_.fields.begin(), header_.fields.end(), [&](const Field& f) { return f.name == name; }))
        fail("field " + shown(name) + " listed twice");
      header_.fields.push_back(Field{std::string(name)});
    }
  }

  void parse_sizes(const std::vector<std::string_view>& values) {
    expect_per_field(values, "SIZE");
    for (size_t i = 0; i < values.size(); ++i) {
      uint64_t size = 0;
      if (!parse_uint(values[i], size) || (size != 1 && size != 2 && size != 4 && size != 8))
        fail("SIZE " + shown(values[i]) + " is not 1, 2, 4 or 8");
      header_.fields[i].size = static_cast<uint32_t>(size);
    }
  }

  void parse_types(const std::vector<std::string_view>& values) {
    expect_per_field(values, "TYPE");
    if (!seen_[kSize]) fail("TYPE before SIZE");
    for (size_t i = 0; i < values.size(); ++i) {
      const std::string_view t = values[i];
      if (t != "I" && t != "U" && t != "F") fail("TYPE " + shown(t) + " is not I, U or F");
      Field& f = header_.fields[i];
      f.type = t.front();
      if (f.type == 'F' && f.size != 4 && f.size != 8)
        fail("field " + shown(f.name) + " is floating point of " + std::to_string(f.size) + " bytes");
    }
  }

  void parse_counts(const std::vector<std::string_view>& values) {
    expect_per_field(values, "COUNT");
    for (size_t i = 0; i < values.size(); ++i) {
      uint64_t count = 0;
      if (!parse_uint(values[i], count) || count == 0 || count > kMaxPointBytes)
        fail("COUNT " + shown(values[i]) + " is not a count from 1 to " + std::to_string(kMaxPointBytes));
      header_.fields[i].count = static_cast<uint32_t>(count);
    }
  }

  uint64_t parse_count(const std::vector<std::string_view>& values, const char* keyword) const {
    uint64_t n = 0;
    if (values.size() != 1 || !parse_uint(values[0], n) || n > std::numeric_limits<uint32_t>::max())
      fail(std::string(keyword) + " needs one count below 2^32, got " +
           (values.empty() ? std::string("nothing") : shown(values[0])));
    return n;
  }

  void parse_viewpoint(const std::vector<std::string_view>& values) {
    if (values.size() != 7) fail("VIEWPOINT needs 7 values (tx ty tz qw qx qy qz)");
    for (size_t i = 0; i < 7; ++i) {
      if (!parse_real(values[i], header_.viewpoint[i]) || !std::isfinite(header_.viewpoint[i]))
        fail("VIEWPOINT value " + shown(values[i]) + " is not a finite number");
    }
    const auto& v = header_.viewpoint;
    const double norm = std::sqrt(double(v[3]) * v[3] + double(v[4]) * v[4] + double(v[5]) * v[5] + double(v[6]) * v[6]);
    if (!(norm > 1e-6)) fail("VIEWPOINT orientation is a zero quaternion");
  }

  void parse_data(const std::vector<std::string_view>& values) {
    if (values.size() != 1) fail("DATA needs one of ascii, binary, binary_compressed");
    if (values[0] == "ascii") header_.encoding = DataEncoding::kAscii;
    else if (values[0] == "binary") header_.encoding = DataEncoding::kBinary;
    else if (values[0] == "binary_compressed") header_.encoding = DataEncoding::kBinaryCompressed;
    else fail("DATA " + shown(values[0]) + " is not ascii, binary or binary_compressed");
  }

  // PCL keeps reading header lines after DATA until one is not a comment or keyword, so a
  // keyword there would silently change what it reads.
  void reject_keywords_after_data(const std::string& text, size_t pos) const {
    while (pos < text.size()) {
      const size_t newline = text.find('\n', pos);
      const size_t end = newline == std::string::npos ? text.size() : newline;
      const std::string_view line = std::string_view(text).substr(pos, end - pos);
      pos = newline == std::string::npos ? text.size() : newline + 1;
      if (line.empty()) continue;
      const std::vector<std::string_view> tokens = split_tokens(line);
      if (tokens.empty()) return;
      if (tokens[0].front() == '#' || tokens[0].substr(0, 7) == "VERSION") continue;
      if (starts_with_pcl_keyword(tokens[0]))
        fail_file("header keyword " + shown(tokens[0]) + " after the DATA line");
      return;
    }
  }

  void check_complete() {
    for (int key : {kFields, kSize, kType, kWidth, kPoints}) {
      if (!seen_[key]) fail_file("header has no " + std::string(kKeywords[key]) + " line");
    }
    if (header_.width * header_.height != header_.points)
      fail_file("WIDTH x HEIGHT (" + std::to_string(header_.width) + " x " + std::to_string(header_.height) +
                ") differs from POINTS (" + std::to_string(header_.points) + ")");
    for (const char* axis : {"x", "y", "z"}) {
      const auto it = std::find_if(header_.fields.begin(), header_.fields.end(),
                                   [&](const Field& f) { return f.name == axis; });
      if (it == header_.fields.end()) fail_file(std::string("no '") + axis + "' field");
      if (it->type != 'F' || it->count != 1)
        fail_file(std::string("field '") + axis + "' is not a single floating-point value");
    }
    if (header_.point_bytes() > kMaxPointBytes)
      fail_file("points of " + std::to_string(header_.point_bytes()) + " bytes each are implausible");
    if (header_.points * header_.point_bytes() > kMaxDataBytes)
      fail_file(std::to_string(header_.points) + " points of " + std::to_string(header_.point_bytes()) +
                " bytes exceed PCL's 4 GiB limit");
  }

  const std::filesystem::path& file_;
  Header header_;
  int line_ = 0;
  int last_ = -1;
  std::array<bool, kKeywords.size()> seen_{};
};

uint32_t read_u32(const char* bytes) {
  uint32_t v = 0;
  std::memcpy(&v, bytes, sizeof v);  // PCD binary data is in host byte order (PCL writes it so)
  return v;
}

void check_binary(const std::filesystem::path& file, uint64_t available, uint64_t data_bytes) {
  if (data_bytes > available)
    throw InputError(file, "PCD: truncated binary data (header promises " + std::to_string(data_bytes) +
                               " bytes, file has " + std::to_string(available) + ")");
}

void check_compressed(const std::filesystem::path& file, std::istream& in, const Header& h, uint64_t available,
                      uint64_t data_bytes) {
  if (available < 8) throw InputError(file, "PCD: truncated before the compressed block sizes");
  char sizes[8];
  in.clear();
  in.seekg(static_cast<std::streamoff>(h.data_offset));
  if (!in.read(sizes, sizeof sizes)) throw InputError(file, "PCD: cannot read the compressed block sizes");
  const uint64_t compressed = read_u32(sizes), uncompressed = read_u32(sizes + 4);
  if (uncompressed != data_bytes)
    throw InputError(file, "PCD: compressed block unpacks to " + std::to_string(uncompressed) +
                               " bytes, header promises " + std::to_string(data_bytes));
  if (compressed > available - 8)
    throw InputError(file, "PCD: truncated compressed data (block of " + std::to_string(compressed) +
                               " bytes, file has " + std::to_string(available - 8) + ")");
  if (data_bytes > compressed * kMaxLzfExpansion)
    throw InputError(file, "PCD: a compressed block of " + std::to_string(compressed) +
                               " bytes cannot unpack to " + std::to_string(data_bytes));
}

void check_ascii(const std::filesystem::path& file, std::istream& in, const Header& h) {
  in.clear();
  in.seekg(static_cast<std::streamoff>(h.data_offset));
  const uint64_t expected = h.values_per_point();
  uint64_t points = 0;
  int line_number = h.data_line - 1;
  std::string line;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.empty()) continue;  // as PCL does
    const std::string where = "PCD line " + std::to_string(line_number) + ": ";
    if (points == h.points)
      throw InputError(file, where + "more point lines than POINTS (" + std::to_string(h.points) + ")");
    const std::vector<std::string_view> tokens = split_tokens(line);
    if (tokens.size() != expected)
      throw InputError(file, where + std::to_string(tokens.size()) + " values, expected " + std::to_string(expected));
    for (std::string_view t : tokens) {
      if (!is_number(t)) throw InputError(file, where + shown(t) + " is not a number");
    }
    ++points;
  }
  if (in.bad()) throw InputError(file, "PCD: read error in the ASCII data");
  if (points < h.points)
    throw InputError(file, "PCD: truncated ASCII data (" + std::to_string(points) + " of " +
                               std::to_string(h.points) + " points)");
}

}  // namespace

uint64_t Header::point_bytes() const {
  uint64_t bytes = 0;
  for (const Field& f : fields) bytes += uint64_t(f.size) * f.count;
  return bytes;
}

uint64_t Header::values_per_point() const {
  uint64_t values = 0;
  for (const Field& f : fields) values += f.count;
  return values;
}

Header read_header(const std::filesystem::path& file, std::istream& in, uint64_t file_size) {
  const uint64_t length = std::min(file_size, kMaxHeaderBytes);
  std::string text(length, '\0');
  if (!in.read(text.data(), static_cast<std::streamsize>(length))) throw InputError(file, "PCD: cannot read the header");
  return HeaderParser(file).parse(text, length == file_size);
}

void check_body(const std::filesystem::path& file, std::istream& in, uint64_t file_size, const Header& header) {
  const uint64_t available = file_size - header.data_offset;
  const uint64_t data_bytes = header.points * header.point_bytes();
  switch (header.encoding) {
    case DataEncoding::kBinary: return check_binary(file, available, data_bytes);
    case DataEncoding::kBinaryCompressed:
      if (header.points == 0) return;
      return check_compressed(file, in, header, available, data_bytes);
    case DataEncoding::kAscii: return check_ascii(file, in, header);
  }
}

}  // namespace bgkmap::pcd
