#include "bgkmap/integrate/host_cells.hpp"

#include <utility>

#include "bgkmap/integrate/integrator.hpp"

namespace bgkmap {

HostCells::HostCells(Integrator& integrator, BgkMap& map, const std::vector<uint32_t>* slots, HostAccess access)
    : integrator_(&integrator), map_(&map), slots_(slots), access_(access) {
  if (access_ != HostAccess::kOverwrite) integrator_->copy_to_host(*map_, slots_);
}

HostCells::HostCells(HostCells&& other) noexcept
    : integrator_(std::exchange(other.integrator_, nullptr)), map_(other.map_), slots_(other.slots_),
      access_(other.access_) {}

HostCells::~HostCells() {
  if (integrator_ && access_ != HostAccess::kRead) integrator_->host_changed(slots_);
}

HostCells Integrator::host_cells(BgkMap& map, IntegrateStats& stats, HostAccess access) {
  finish(stats);
  return HostCells(*this, map, nullptr, access);
}

HostCells Integrator::host_cells(BgkMap& map, const std::vector<uint32_t>& slots, IntegrateStats& stats,
                                 HostAccess access) {
  finish(stats);
  return HostCells(*this, map, &slots, access);
}

}  // namespace bgkmap
