// Which copy of the map's cells is current, as a scoped object. A back end may keep the map's
// cells elsewhere (the OpenCL device does, between scans); a HostCells view makes the host's cells
// current when it opens and hands the host's writes to the back end when it closes, so a caller
// never orders the copies itself. Views come from Integrator::host_cells().
#pragma once

#include <cstdint>
#include <vector>

namespace bgkmap {

class BgkMap;
class Integrator;

enum class HostAccess {
  kRead,       // the host reads the cells: copied back when the view opens
  kReadWrite,  // reads and changes them: copied back when it opens, taken by the back end when it closes
  kOverwrite,  // writes them without reading (what the host holds is newer): taken when it closes, no copy back
};

class HostCells {
 public:
  HostCells(const HostCells&) = delete;
  HostCells& operator=(const HostCells&) = delete;
  HostCells(HostCells&& other) noexcept;
  HostCells& operator=(HostCells&&) = delete;
  // kReadWrite, kOverwrite: the back end takes the host's cells of the view's slots before it next
  // integrates or copies cells back.
  ~HostCells();

  BgkMap& map() const { return *map_; }

 private:
  friend class Integrator;
  // slots null: every slot of the map; else they must outlive the view.
  HostCells(Integrator& integrator, BgkMap& map, const std::vector<uint32_t>* slots, HostAccess access);

  Integrator* integrator_;  // null once moved from
  BgkMap* map_;
  const std::vector<uint32_t>* slots_;
  HostAccess access_;
};

}  // namespace bgkmap
