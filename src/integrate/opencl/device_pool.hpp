// Private to the OpenCL back end: the device's copy of the map's cell pool, slot for slot.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <vector>

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
  // limit_bytes: the most device memory the pool may take (one buffer). host_memory: the device
  // works in the host's memory (a CPU device), so write_slots and read_slots map the pool and copy
  // the slots there; otherwise they pack them on the device and make one transfer.
  DeviceCellPool(cl::Context context, size_t limit_bytes, bool host_memory);

  // Makes the device hold every slot of `map`. from_host: all of them are taken from the host's
  // cells (a map seen for the first time, e.g. a resumed one, or changed on the host); otherwise
  // the device keeps the slots it has and the new ones start at the prior, as BgkMap::ensure_slot
  // starts them on the host. Grows the buffer when full; throws DeviceMemoryExhausted beyond the
  // limit and cl::Error when the device refuses. On a throw the slots held before stay valid
  // (unless from_host: then the host's cells are the map and the device holds none).
  void mirror(cl::CommandQueue& queue, const BgkMap& map, bool from_host);

  // Copies the device's slots into the map's host cells (blocking).
  void read_back(cl::CommandQueue& queue, BgkMap& map) const;

  // Copies these slots (held by the device: mirror first) from the host's cells to the device,
  // or back (both blocking): in the mapped pool, or packed on the device by `scatter` and
  // `gather` (bgk_pool_scatter, bgk_pool_gather) with one transfer per kSlotsPerCopy slots.
  void write_slots(cl::CommandQueue& queue, const BgkMap& map, const std::vector<uint32_t>& slots, cl::Kernel& scatter);
  void read_slots(cl::CommandQueue& queue, BgkMap& map, const std::vector<uint32_t>& slots, cl::Kernel& gather);

  // Queues `decay` (bgk_pool_decay) over these slots (held by the device), slot i by factors[i];
  // returns without waiting for the queue.
  void decay_slots(cl::CommandQueue& queue, const BgkMap& map, const std::vector<uint32_t>& slots,
                   const std::vector<float>& factors, cl::Kernel& decay);

  // Allocates the packed copies' buffers (a device with its own memory) for blocks of `cells`
  // cells, so that a refusal comes before the first scan, not in the middle of one.
  void prepare_slot_copies(size_t cells);

  const cl::Buffer& buffer() const { return buffer_; }
  size_t slots() const { return slots_; }

 private:
  void reserve(cl::CommandQueue& queue, size_t slots, size_t slot_bytes);
  static constexpr size_t kSlotsPerCopy = 4096;  // 16 MiB of 8^3 blocks

  // The pool's range from the least to the greatest of `slots` mapped for `flags`; copy(the
  // mapped address of slot 0, as if the whole pool were mapped).
  template <class Copy>
  void in_mapped_range(cl::CommandQueue& queue, const std::vector<uint32_t>& slots, size_t slot_bytes, cl_map_flags flags,
                       Copy&& copy) const;

  cl::Context context_;
  size_t limit_bytes_;
  bool host_memory_;
  cl::Buffer buffer_;
  size_t capacity_bytes_ = 0;
  size_t slots_ = 0;  // slots that hold the map's cells
  cl::Buffer slot_list_, packed_;  // a packed copy's slots and cells
  size_t packed_cells_ = 0;        // cells per slot packed_ is sized for
  std::vector<Cell> packed_host_;
};

}  // namespace bgkmap::opencl_detail
