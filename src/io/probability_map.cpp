// Probability maps (gpom, wgpom, gpoctomap, bhm) by extension: trees or exports.
#include "io/probability_map.hpp"

#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_export.hpp"
#include "bgkmap/io/map_io.hpp"

namespace bgkmap {

void require_probability_map_output(const std::filesystem::path& file, const std::string& method) {
  if (map_format_from_path(file) == MapFormat::kNative)
    throw InputError(file, "--method " + method +
                               " keeps no Beta posterior: it writes .ot, .bt, .pgm, .ply or .pcd, not a native .bgk map");
}

ExportCells probability_export_cells(double resolution_m, const ClassifyParams& classify,
                                     const CellProbabilities& cells) {
  ExportCells out;
  out.resolution_m = resolution_m;
  out.has_variance = false;
  out.for_each = [&classify, &cells](const ExportCellVisitor& visit) {
    cells([&](const CellIndex& index, double p) {
      visit(ExportCell{index, state_of_probability(p, classify), p, 0.0});
    });
  };
  return out;
}

void write_probability_map(const std::filesystem::path& file, double resolution_m, const ClassifyParams& classify,
                           const CellProbabilities& cells, TreeValues ot_values) {
  if (is_export_format(map_format_from_path(file)))
    return write_map_export(file, probability_export_cells(resolution_m, classify, cells));
  write_probability_tree(file, resolution_m, classify, cells, ot_values);
}

}  // namespace bgkmap
