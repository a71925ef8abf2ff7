// BGK-L (and the baselines that are BGK-L with other observations or kernel): the Mapper's map,
// every output format map_io writes.
#include <memory>
#include <utility>

#include "bgkmap/io/map_io.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/bgkl/bgk_map_method.hpp"

namespace bgkmap {

BgkMapMethod::BgkMapMethod(std::string name, std::unique_ptr<Mapper> mapper)
    : name_(std::move(name)), mapper_(std::move(mapper)) {}

void BgkMapMethod::check_output(const std::filesystem::path& file) const { map_format_from_path(file); }

void BgkMapMethod::insert_prepared(PreparedScan&& prepared) { mapper_->insert_prepared(std::move(prepared)); }

void BgkMapMethod::finish() { mapper_->finish(); }

void BgkMapMethod::write_file(const std::filesystem::path& file, TreeValues ot_values) {
  write_map(file, mapper_->map(), name(), ot_values);
}

std::optional<CellEstimate> beta_estimate(const CellPosterior& posterior) {
  if (!posterior.has_evidence) return std::nullopt;
  CellEstimate e;
  e.occupancy = posterior.mean();
  e.variance = posterior.variance();
  e.beta = posterior;
  return e;
}

std::optional<CellEstimate> BgkMapMethod::estimate_cell(double x, double y, double z) {
  return beta_estimate(mapper_->map().query(x, y, z));
}

uint64_t BgkMapMethod::blocks_touched() { return mapper_->map().block_count(); }

uint64_t BgkMapMethod::known_cells() { return mapper_->map().cells_with_evidence(); }

std::unique_ptr<MappingMethod> make_bgkl_method(std::unique_ptr<Mapper> mapper) {
  return std::make_unique<BgkMapMethod>("bgkl", std::move(mapper));
}

}  // namespace bgkmap
