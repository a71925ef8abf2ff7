// Checks a PCD file before PCL reads it. PCL's reader trusts the header: it allocates
// POINTS x point size bytes as soon as it sees POINTS, keeps parsing header keywords after the DATA
// line, and fills malformed or missing ASCII points with zeros without failing. So the header is
// parsed here, strictly (the order the PCD spec prescribes, every keyword once, exact values),
// and the body is checked to hold exactly what the header promises, before PCL sees the file.
// Bytes after the binary data are allowed (older PCL writers pad files with zeros).
// Internal to src/io.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <istream>
#include <string>
#include <vector>

namespace bgkmap::pcd {

enum class DataEncoding { kAscii, kBinary, kBinaryCompressed };

struct Field {
  std::string name;
  uint32_t size = 4;   // bytes per value: 1, 2, 4 or 8
  char type = 'F';     // I (signed), U (unsigned) or F (floating point)
  uint32_t count = 1;  // values per point
};

struct Header {
  std::vector<Field> fields;
  uint64_t width = 0;
  uint64_t height = 1;
  uint64_t points = 0;
  std::array<float, 7> viewpoint{0, 0, 0, 1, 0, 0, 0};  // tx ty tz qw qx qy qz, as written
  DataEncoding encoding = DataEncoding::kAscii;
  uint64_t data_offset = 0;  // first byte after the DATA line
  int data_line = 0;         // line number of the first line after DATA (for ASCII messages)

  uint64_t point_bytes() const;   // sum of size x count over the fields
  uint64_t values_per_point() const;  // sum of count over the fields
};

// Parses and checks the header; `in` must be positioned at the start of the file, and
// `file_size` is its length. Throws InputError naming `file` on anything malformed.
Header read_header(const std::filesystem::path& file, std::istream& in, uint64_t file_size);

// Checks that the body holds exactly what `header` promises, without decoding values: enough
// binary bytes, consistent compressed-block sizes, or for ASCII one line of numbers per point.
// Throws InputError naming `file` otherwise.
void check_body(const std::filesystem::path& file, std::istream& in, uint64_t file_size, const Header& header);

}  // namespace bgkmap::pcd
