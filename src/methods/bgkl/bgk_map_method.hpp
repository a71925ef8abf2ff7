// The MappingMethod of the BGK-L Mapper, and what every method with a BgkMap (bgkl, bgk, counting)
// answers for a cell.
#pragma once

#include <memory>
#include <optional>
#include <string>

#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// forget-half-life: the half-life in scans of every observation's evidence, 0 = off
// (map/forgetting.hpp); bgkl declares it, bgk and counting read it too (bgkl_descriptor.cpp).
const ParamSpec& forget_half_life_param();

// A BgkMap cell's estimate: the Beta posterior's mean and variance; nullopt without evidence.
std::optional<CellEstimate> beta_estimate(const CellPosterior& posterior);

class BgkMapMethod : public MappingMethod {
 public:
  BgkMapMethod(std::string name, std::unique_ptr<Mapper> mapper);

  std::string name() const override { return name_; }
  bool uses_pose_uncertainty() const override { return true; }  // the Mapper's expected sub-map or kernel
  void check_output(const std::filesystem::path& file) const override;
  void insert_prepared(PreparedScan&& prepared) override;
  void finish() override;
  void write_file(const std::filesystem::path& file, TreeValues ot_values) override;
  std::optional<CellEstimate> estimate_cell(double x, double y, double z) override;
  const BuildParams& params() const override { return mapper_->params(); }
  const BuildCounts& counts() const override { return mapper_->counts(); }
  const InsertTiming& timing() const override { return mapper_->timing(); }
  BackendInfo backend() const override { return mapper_->backend(); }
  uint64_t blocks_touched() override;
  uint64_t known_cells() override;

 private:
  std::string name_;
  std::unique_ptr<Mapper> mapper_;
};

}  // namespace bgkmap
