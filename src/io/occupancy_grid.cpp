// Occupancy grids for ROS map_server: the projection of a map onto the plane and its PGM + YAML.
#include "bgkmap/io/occupancy_grid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "core/number_text.hpp"

namespace bgkmap {

namespace {

double cell_centre_z(int32_t index, double resolution_m) { return (index + 0.5) * resolution_m; }

// The class a column takes from one more cell of it: occupied wins, then free, then unknown.
CellState merged(CellState column, CellState cell) {
  return static_cast<CellState>(std::max(static_cast<int>(column), static_cast<int>(cell)));
}

// The fewest decimals that read back as the same double (0.1 stays "0.1"), never an exponent
// or a bare integer: YAML 1.1 readers (PyYAML) take "1e+06" and "-1" for strings or ints.
std::string round_trip_text(double value) {
  char text[64];
  for (int decimals = 1; decimals <= 30; ++decimals) {
    std::snprintf(text, sizeof text, "%.*f", decimals, value);
    if (std::strtod(text, nullptr) == value) return text;
  }
  std::snprintf(text, sizeof text, "%.17g", value);
  return text;
}

// A YAML double-quoted scalar: a file name may hold ':', '#' or spaces.
std::string yaml_quoted(const std::string& text) {
  std::string quoted = "\"";
  for (const char c : text) {
    if (c == '"' || c == '\\') quoted += '\\';
    quoted += c;
  }
  return quoted + "\"";
}

unsigned char ros_pixel(CellState state) {
  switch (state) {
    case CellState::kOccupied: return kRosOccupiedPixel;
    case CellState::kFree: return kRosFreePixel;
    case CellState::kUnknown: break;
  }
  return kRosUnknownPixel;
}

}  // namespace

HeightBand height_band_between(double z_min, double z_max) {
  if (!std::isfinite(z_min) || !std::isfinite(z_max) || z_min > z_max)
    throw std::invalid_argument("--z-min and --z-max must be finite with --z-min <= --z-max (got " + number_text(z_min) +
                                ", " + number_text(z_max) + ")");
  HeightBand band;
  band.z_min = z_min, band.z_max = z_max;
  return band;
}

OccupancyGrid project_occupancy(const ExportCells& cells, const HeightBand& band, const std::filesystem::path& output) {
  if (cells.planar && !band.is_every_height())
    throw InputError(output, "a planar (--2d) map has one layer of cells: drop --z-min/--z-max");
  const double r = cells.resolution_m;
  int32_t lo_x = INT32_MAX, lo_y = INT32_MAX, hi_x = INT32_MIN, hi_y = INT32_MIN;
  cells.for_each([&](const ExportCell& c) {
    if (!band.contains(cell_centre_z(c.index.z, r))) return;
    lo_x = std::min(lo_x, c.index.x), hi_x = std::max(hi_x, c.index.x);
    lo_y = std::min(lo_y, c.index.y), hi_y = std::max(hi_y, c.index.y);
  });
  if (lo_x > hi_x) {
    if (band.is_every_height()) throw InputError(output, "the map has no cell with evidence: nothing to export");
    throw InputError(output, "no cell with evidence has its centre at heights [" + number_text(band.z_min) + ", " +
                                 number_text(band.z_max) + "] m: widen --z-min/--z-max");
  }
  OccupancyGrid grid;
  grid.resolution_m = r;
  grid.min_x = lo_x, grid.min_y = lo_y;
  grid.width = static_cast<int>(int64_t{hi_x} - lo_x + 1);
  grid.height = static_cast<int>(int64_t{hi_y} - lo_y + 1);
  const double pixels = double(grid.width) * grid.height;
  require_memory(2 * pixels * sizeof(CellState), "the occupancy grid of " + output.filename().string() + " (" +
                 std::to_string(grid.width) + " x " + std::to_string(grid.height) + " cells)",
                 "give a height band (--z-min/--z-max) or a coarser --resolution (or raise --max-memory)");
  grid.states.assign(static_cast<size_t>(pixels), CellState::kUnknown);
  cells.for_each([&](const ExportCell& c) {
    if (!band.contains(cell_centre_z(c.index.z, r))) return;
    CellState& column = grid.states[static_cast<size_t>(c.index.y - lo_y) * grid.width + (c.index.x - lo_x)];
    column = merged(column, c.state);
  });
  return grid;
}

std::filesystem::path ros_map_yaml_path(const std::filesystem::path& pgm) {
  std::filesystem::path yaml = pgm;
  return yaml.replace_extension(".yaml");
}

void write_ros_map(const std::filesystem::path& pgm, const OccupancyGrid& grid) {
  write_file_atomically(pgm, [&](std::ostream& out) {
    out << "P5\n" << grid.width << ' ' << grid.height << "\n255\n";
    std::string row(static_cast<size_t>(grid.width), '\0');
    for (int y = grid.height - 1; y >= 0; --y) {  // the image's first row is the max-y edge
      for (int x = 0; x < grid.width; ++x) row[x] = static_cast<char>(ros_pixel(grid.at(x, y)));
      out.write(row.data(), static_cast<std::streamsize>(row.size()));
    }
  });
  write_file_atomically(ros_map_yaml_path(pgm), [&](std::ostream& out) {
    out << "image: " << yaml_quoted(pgm.filename().string()) << "\n"
        << "resolution: " << round_trip_text(grid.resolution_m) << "\n"
        << "origin: [" << round_trip_text(grid.origin_x()) << ", " << round_trip_text(grid.origin_y()) << ", 0.0]\n"
        << "negate: 0\n"
        << "occupied_thresh: " << round_trip_text(kRosOccupiedThresh) << "\n"
        << "free_thresh: " << round_trip_text(kRosFreeThresh) << "\n"
        << "mode: trinary\n";
  });
}

}  // namespace bgkmap
