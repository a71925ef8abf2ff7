#include "device_pool.hpp"

#include <algorithm>
#include <string>
#include <utility>

namespace bgkmap::opencl_detail {

namespace {
std::string mib(size_t bytes) { return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB"; }
}  // namespace

DeviceCellPool::DeviceCellPool(cl::Context context, size_t limit_bytes)
    : context_(std::move(context)), limit_bytes_(limit_bytes) {}

void DeviceCellPool::reserve(cl::CommandQueue& queue, size_t slots, size_t slot_bytes) {
  const size_t needed = slots * slot_bytes;
  if (needed <= capacity_bytes_) return;
  if (needed > limit_bytes_)
    throw DeviceMemoryExhausted("the map needs " + mib(needed) + " of device memory for its " + std::to_string(slots) +
                                " blocks, more than the " + mib(limit_bytes_) + " the device allows in one buffer");
  // Doubling keeps the copies of a growing map linear in its final size.
  const size_t limit_slots = limit_bytes_ / slot_bytes;
  const size_t capacity = std::min(limit_slots, std::max({slots, 2 * capacity_bytes_ / slot_bytes, size_t(64)}));
  cl::Buffer bigger(context_, CL_MEM_READ_WRITE, capacity * slot_bytes);
  if (slots_ > 0) queue.enqueueCopyBuffer(buffer_, bigger, 0, 0, slots_ * slot_bytes);
  buffer_ = std::move(bigger);  // the old buffer lives on until the copy is done
  capacity_bytes_ = capacity * slot_bytes;
}

void DeviceCellPool::mirror(cl::CommandQueue& queue, const BgkMap& map, bool from_host) {
  const size_t slot_bytes = sizeof(Cell) * static_cast<size_t>(map.cells_per_block());
  const size_t wanted = map.block_count();
  const size_t kept = from_host ? 0 : slots_;
  if (from_host) slots_ = 0;  // nothing on the device is worth copying into a bigger buffer
  reserve(queue, wanted, slot_bytes);
  if (wanted > kept) {
    if (from_host) {
      queue.enqueueWriteBuffer(buffer_, CL_TRUE, 0, wanted * slot_bytes, map.cell_pool().data());
    } else {
      const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
      queue.enqueueFillBuffer(buffer_, prior, kept * slot_bytes, (wanted - kept) * slot_bytes);
    }
  }
  slots_ = wanted;
}

void DeviceCellPool::read_back(cl::CommandQueue& queue, BgkMap& map) const {
  if (slots_ == 0) return;
  const size_t slot_bytes = sizeof(Cell) * static_cast<size_t>(map.cells_per_block());
  queue.enqueueReadBuffer(buffer_, CL_TRUE, 0, slots_ * slot_bytes, map.cell_pool().data());
}

}  // namespace bgkmap::opencl_detail
