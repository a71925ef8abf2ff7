// Occupied cells as PLY / PCD points with their probability and variance.
#include "bgkmap/io/cell_cloud.hpp"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/io/atomic_file.hpp"

namespace bgkmap {

namespace {

// Each occupied cell's float fields, point after point: x y z probability [variance].
struct CloudFields {
  int per_point = 0;
  std::vector<float> values;
  size_t points() const { return per_point == 0 ? 0 : values.size() / per_point; }
};

CloudFields occupied_fields(const std::filesystem::path& file, const ExportCells& cells) {
  CloudFields fields;
  fields.per_point = cells.has_variance ? 5 : 4;
  size_t occupied = 0;
  cells.for_each([&](const ExportCell& c) { occupied += c.state == CellState::kOccupied; });
  require_memory(double(occupied) * fields.per_point * sizeof(float) * 2,
                 "the occupied cells of " + file.filename().string() + " (" + std::to_string(occupied) + ")",
                 "give a coarser --resolution (or raise --max-memory)");
  fields.values.reserve(occupied * fields.per_point);
  const double r = cells.resolution_m;
  cells.for_each([&](const ExportCell& c) {
    if (c.state != CellState::kOccupied) return;
    for (const double v : {(c.index.x + 0.5) * r, (c.index.y + 0.5) * r, (c.index.z + 0.5) * r, c.probability})
      fields.values.push_back(static_cast<float>(v));
    if (cells.has_variance) fields.values.push_back(static_cast<float>(c.variance));
  });
  return fields;
}

// The values as little-endian IEEE-754 binary32, whatever the host's byte order.
void write_little_endian(std::ostream& out, const std::vector<float>& values) {
  std::string bytes(values.size() * 4, '\0');
  for (size_t i = 0; i < values.size(); ++i) {
    uint32_t bits;
    std::memcpy(&bits, &values[i], 4);
    for (int b = 0; b < 4; ++b) bytes[4 * i + b] = static_cast<char>((bits >> (8 * b)) & 0xFF);
  }
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace

void write_occupied_cells_ply(const std::filesystem::path& file, const ExportCells& cells) {
  const CloudFields fields = occupied_fields(file, cells);
  write_file_atomically(file, [&](std::ostream& out) {
    out << "ply\nformat binary_little_endian 1.0\n"
        << "comment bgkmap occupied cells: centre (m), probability = P(occupied)"
        << (cells.has_variance ? ", variance of the posterior\n" : " (the method keeps no variance)\n")
        << "element vertex " << fields.points() << "\n"
        << "property float x\nproperty float y\nproperty float z\nproperty float probability\n"
        << (cells.has_variance ? "property float variance\n" : "") << "end_header\n";
    write_little_endian(out, fields.values);
  });
}

void write_occupied_cells_pcd(const std::filesystem::path& file, const ExportCells& cells) {
  const CloudFields fields = occupied_fields(file, cells);
  write_file_atomically(file, [&](std::ostream& out) {
    const bool variance = cells.has_variance;
    out << "# .PCD v0.7 - bgkmap occupied cells: centre (m), probability = P(occupied)"
        << (variance ? ", variance of the posterior\n" : " (the method keeps no variance)\n")
        << "VERSION 0.7\n"
        << "FIELDS x y z probability" << (variance ? " variance" : "") << "\n"
        << "SIZE 4 4 4 4" << (variance ? " 4" : "") << "\n"
        << "TYPE F F F F" << (variance ? " F" : "") << "\n"
        << "COUNT 1 1 1 1" << (variance ? " 1" : "") << "\n"
        << "WIDTH " << fields.points() << "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\n"
        << "POINTS " << fields.points() << "\nDATA binary\n";
    // PCD's binary data is the writer's memory layout; PCL and every common reader take it as little-endian.
    write_little_endian(out, fields.values);
  });
}

}  // namespace bgkmap
