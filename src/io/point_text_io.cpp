// The only translation unit that includes PCL's PLY reader.
#include "bgkmap/io/point_text_io.hpp"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/ply_io.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <new>
#include <sstream>
#include <string>

#include "bgkmap/io/errors.hpp"
#include "input_file.hpp"
#include "text_lines.hpp"

namespace bgkmap {

using io_detail::parse_number;
using io_detail::split_fields;
using io_detail::TextLines;

Scan read_xyz(const std::filesystem::path& file) {
  TextLines lines(file);
  Scan scan;
  scan.source = file.string();
  scan.has_own_pose = false;
  std::string line;
  while (lines.next(line)) {
    const auto f = split_fields(line);
    if (f.empty() || f[0].front() == '#' || f[0].rfind("//", 0) == 0) continue;
    double v[3];
    if (f.size() < 3) lines.fail("XYZ: " + std::to_string(f.size()) + " fields, expected x y z");
    for (int i = 0; i < 3; ++i)
      if (!parse_number(f[i], v[i])) lines.fail("XYZ: field " + std::to_string(i + 1) + " is not a number");
    scan.points.push_back({static_cast<float>(v[0]), static_cast<float>(v[1]), static_cast<float>(v[2])});
  }
  return scan;
}

namespace {

// What read_ply checks before PCL sees the file.
struct PlyLayout {
  enum class Format { kAscii, kBinaryLittle, kBinaryBig } format = Format::kAscii;
  uint64_t header_bytes = 0;
  uint64_t vertices = 0;
  uint64_t min_body_bytes = 0;  // binary: exact when no element has list properties
  bool has_lists = false;
};

int ply_type_size(const std::string& t) {
  static const std::map<std::string, int> sizes = {
      {"char", 1},  {"uchar", 1},  {"int8", 1},   {"uint8", 1},  {"short", 2},   {"ushort", 2},  {"int16", 2},
      {"uint16", 2}, {"int", 4},   {"uint", 4},   {"int32", 4},  {"uint32", 4},  {"float", 4},   {"float32", 4},
      {"double", 8}, {"float64", 8}};
  const auto it = sizes.find(t);
  return it == sizes.end() ? 0 : it->second;
}

PlyLayout check_ply_header(const std::filesystem::path& file, uint64_t file_size) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open for reading");
  PlyLayout layout;
  std::string line;
  const auto fail = [&](const std::string& what) -> void { throw InputError(file, "PLY: " + what); };
  if (!std::getline(in, line) || (line != "ply" && line != "ply\r")) fail("no 'ply' magic line");
  struct Element {
    std::string name;
    uint64_t count = 0;
    uint64_t bytes = 0;  // per item, scalar properties (lists: their count field only)
    std::map<std::string, std::string> scalars;
  };
  std::vector<Element> elements;
  bool format_seen = false, ended = false;
  constexpr size_t kMaxHeaderLines = 10000;
  for (size_t n = 0; n < kMaxHeaderLines && std::getline(in, line); ++n) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::istringstream words(line);
    std::string key;
    words >> key;
    if (key == "end_header") {
      ended = true;
      break;
    }
    if (key == "comment" || key == "obj_info" || key.empty()) continue;
    if (key == "format") {
      std::string f, version;
      words >> f >> version;
      if (f == "ascii") layout.format = PlyLayout::Format::kAscii;
      else if (f == "binary_little_endian") layout.format = PlyLayout::Format::kBinaryLittle;
      else if (f == "binary_big_endian") layout.format = PlyLayout::Format::kBinaryBig;
      else fail("unknown format '" + f + "'");
      format_seen = true;
    } else if (key == "element") {
      Element e;
      std::string count;
      words >> e.name >> count;
      if (count.empty() || count.find_first_not_of("0123456789") != std::string::npos || count.size() > 15)
        fail("element '" + e.name + "' has no valid count");
      e.count = std::stoull(count);
      elements.push_back(e);
    } else if (key == "property") {
      if (elements.empty()) fail("a property before any element");
      std::string type;
      words >> type;
      if (type == "list") {
        std::string count_type, item_type, name;
        words >> count_type >> item_type >> name;
        if (!ply_type_size(count_type) || !ply_type_size(item_type)) fail("list property '" + name + "' has an unknown type");
        // PCL reads a vertex list into fixed-size point fields and aborts (an assert) when a
        // later vertex's list is longer than the first's; point clouds have none.
        if (elements.back().name == "vertex")
          fail("the vertex element has a list property '" + name + "' (not supported)");
        elements.back().bytes += ply_type_size(count_type);
        layout.has_lists = true;
      } else {
        std::string name;
        words >> name;
        if (!ply_type_size(type)) fail("property '" + name + "' has unknown type '" + type + "'");
        elements.back().bytes += ply_type_size(type);
        elements.back().scalars[name] = type;
      }
    } else {
      fail("unknown header line '" + io_detail::excerpt(line) + "'");
    }
  }
  if (!ended) fail("no end_header line");
  if (!format_seen) fail("no format line");
  layout.header_bytes = static_cast<uint64_t>(in.tellg());
  const Element* vertex = nullptr;
  for (const Element& e : elements)
    if (e.name == "vertex") vertex = &e;
  if (!vertex) fail("no vertex element");
  for (const char* axis : {"x", "y", "z"}) {
    const auto it = vertex->scalars.find(axis);
    if (it == vertex->scalars.end()) fail(std::string("the vertex element has no '") + axis + "' property");
    if (ply_type_size(it->second) < 4 || (it->second != "float" && it->second != "float32" && it->second != "double" && it->second != "float64"))
      fail(std::string("vertex property '") + axis + "' is not float or double");
  }
  layout.vertices = vertex->count;
  const uint64_t body = file_size - layout.header_bytes;
  for (const Element& e : elements) {
    // Every item takes at least its scalar bytes (binary) or two bytes a property (ascii: a
    // digit and a separator), so no count the file cannot hold reaches PCL's allocations.
    const uint64_t per_item = layout.format == PlyLayout::Format::kAscii ? 2 * std::max<uint64_t>(1, e.scalars.size()) : e.bytes;
    if (per_item > 0 && e.count > body / per_item)
      fail("element '" + e.name + "' claims " + std::to_string(e.count) + " items, the file has " + std::to_string(body) +
           " bytes after the header");
    layout.min_body_bytes += e.count * per_item;
  }
  if (layout.min_body_bytes > body)
    fail("truncated data (expected at least " + std::to_string(layout.min_body_bytes) + " bytes, found " +
         std::to_string(body) + ")");
  if (layout.format != PlyLayout::Format::kAscii && !layout.has_lists && layout.min_body_bytes != body)
    fail("binary data of " + std::to_string(body) + " bytes, the header describes " + std::to_string(layout.min_body_bytes));
  return layout;
}

}  // namespace

Scan read_ply(const std::filesystem::path& file) {
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);  // errors come back as InputError
  const uint64_t file_size = io_detail::input_file_size(file);
  const PlyLayout layout = check_ply_header(file, file_size);

  Scan scan;
  scan.source = file.string();
  scan.has_own_pose = false;
  if (layout.vertices == 0) return scan;
  io_detail::require_read_memory(file, layout.vertices, double(file_size - layout.header_bytes) / layout.vertices + sizeof(Vec3f));
  pcl::PCLPointCloud2 blob;
  int result = -1;
  try {
    result = pcl::PLYReader().read(file.string(), blob);
  } catch (const std::bad_alloc&) {
    throw InputError(file, "PLY: out of memory decoding " + std::to_string(layout.vertices) + " vertices");
  } catch (const std::exception& e) {
    throw InputError(file, std::string("PLY: PCL cannot decode the data (") + e.what() + ")");
  }
  const uint64_t points = uint64_t(blob.width) * blob.height;
  if (result < 0 || points != layout.vertices || blob.data.size() < points * blob.point_step)
    throw InputError(file, "PLY: PCL cannot decode " + std::to_string(layout.vertices) + " vertices (bad or truncated data)");
  int offsets[3] = {-1, -1, -1};
  bool is_double[3] = {false, false, false};
  for (const pcl::PCLPointField& f : blob.fields)
    for (int a = 0; a < 3; ++a)
      if (f.name == std::string(1, "xyz"[a]) && f.count == 1 &&
          (f.datatype == pcl::PCLPointField::FLOAT32 || f.datatype == pcl::PCLPointField::FLOAT64)) {
        is_double[a] = f.datatype == pcl::PCLPointField::FLOAT64;
        if (uint64_t(f.offset) + (is_double[a] ? 8 : 4) <= blob.point_step) offsets[a] = static_cast<int>(f.offset);
      }
  for (int a = 0; a < 3; ++a)
    if (offsets[a] < 0) throw InputError(file, std::string("PLY: no '") + "xyz"[a] + "' field after decoding");
  scan.points.resize(points);
  for (uint64_t i = 0; i < points; ++i) {
    const uint8_t* p = blob.data.data() + i * blob.point_step;
    float v[3];
    for (int a = 0; a < 3; ++a) {
      if (is_double[a]) {
        double d;
        std::memcpy(&d, p + offsets[a], sizeof d);
        v[a] = static_cast<float>(d);
      } else {
        std::memcpy(&v[a], p + offsets[a], sizeof v[a]);
      }
    }
    scan.points[i] = {v[0], v[1], v[2]};
  }
  return scan;
}

}  // namespace bgkmap
