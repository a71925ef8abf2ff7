// The map exports dispatched by extension.
#include "bgkmap/io/map_export.hpp"

#include "bgkmap/io/cell_cloud.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"

namespace bgkmap {

void write_map_export(const std::filesystem::path& file, const ExportCells& cells, const HeightBand& band) {
  switch (map_format_from_path(file)) {
    case MapFormat::kRosMap: return write_ros_map(file, project_occupancy(cells, band, file));
    case MapFormat::kPlyCloud: return write_occupied_cells_ply(file, cells);
    case MapFormat::kPcdCloud: return write_occupied_cells_pcd(file, cells);
    case MapFormat::kNative:
    case MapFormat::kOctomapTree:
    case MapFormat::kOctomapBinary: break;
  }
  throw InputError(file, "not a map export (expected .pgm, .ply or .pcd)");
}

}  // namespace bgkmap
