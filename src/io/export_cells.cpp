// A BGK map as the cells its exports are written from.
#include "bgkmap/io/export_cells.hpp"

namespace bgkmap {

ExportCells export_cells(const BgkMap& map) {
  ExportCells cells;
  cells.resolution_m = map.grid().resolution();
  cells.planar = map.params().preprocess.planar;
  cells.has_variance = true;
  cells.for_each = [&map](const ExportCellVisitor& visit) {
    const ClassifyParams& classify = map.params().classify;
    map.for_each_cell_with_evidence([&](const CellIndex& index, const CellPosterior& p) {
      visit(ExportCell{index, p.state(classify), p.mean(), p.variance()});
    });
  };
  return cells;
}

}  // namespace bgkmap
