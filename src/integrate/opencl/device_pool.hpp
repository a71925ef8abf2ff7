// Private to the OpenCL back end: the device's copy of the map's cell pool, slot for slot.
#pragma once

#include <cstddef>
#include <stdexcept>

#include "bgkmap/map/bgk_map.hpp"
#include "opencl_runtime.hpp"

namespace bgkmap::opencl_detail {

// The pool would outgrow the device memory the back end may use.
class DeviceMemoryExhausted : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class DeviceCellPool {
 public:
  // limit_bytes: the most device memory the pool may take (one buffer).
  DeviceCellPool(cl::Context context, size_t limit_bytes);

  // Makes the device hold every slot of `map`. from_host: all of them are taken from the host's
  // cells (a map seen for the first time, e.g. a resumed one, or changed on the host); otherwise
  // the device keeps the slots it has and the new ones start at the prior, as BgkMap::ensure_slot
  // starts them on the host. Grows the buffer when full; throws DeviceMemoryExhausted beyond the
  // limit and cl::Error when the device refuses. On a throw the slots held before stay valid
  // (unless from_host: then the host's cells are the map and the device holds none).
  void mirror(cl::CommandQueue& queue, const BgkMap& map, bool from_host);

  // Copies the device's slots into the map's host cells (blocking).
  void read_back(cl::CommandQueue& queue, BgkMap& map) const;

  const cl::Buffer& buffer() const { return buffer_; }
  size_t slots() const { return slots_; }

 private:
  void reserve(cl::CommandQueue& queue, size_t slots, size_t slot_bytes);

  cl::Context context_;
  size_t limit_bytes_;
  cl::Buffer buffer_;
  size_t capacity_bytes_ = 0;
  size_t slots_ = 0;  // slots that hold the map's cells
};

}  // namespace bgkmap::opencl_detail
