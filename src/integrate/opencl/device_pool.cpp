#include "device_pool.hpp"

#include <algorithm>
#include <string>
#include <utility>

namespace bgkmap::opencl_detail {

namespace {
std::string mib(size_t bytes) { return std::to_string((bytes + (1u << 20) - 1) >> 20) + " MiB"; }
}  // namespace

DeviceCellPool::DeviceCellPool(cl::Context context, size_t limit_bytes, bool host_memory)
    : context_(std::move(context)), limit_bytes_(limit_bytes), host_memory_(host_memory) {}

template <class Copy>
void DeviceCellPool::in_mapped_range(cl::CommandQueue& queue, const std::vector<uint32_t>& slots, size_t slot_bytes,
                                     cl_map_flags flags, Copy&& copy) const {
  const auto [least, greatest] = std::minmax_element(slots.begin(), slots.end());
  const size_t first = *least, count = size_t(*greatest) - first + 1;
  void* mapped = queue.enqueueMapBuffer(buffer_, CL_TRUE, flags, first * slot_bytes, count * slot_bytes);
  copy(static_cast<char*>(mapped) - first * slot_bytes);
  queue.enqueueUnmapMemObject(buffer_, mapped);
  queue.finish();
}

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

void DeviceCellPool::prepare_slot_copies(size_t cells) {
  if (host_memory_ || packed_cells_ == cells) return;
  slot_list_ = cl::Buffer(context_, CL_MEM_READ_ONLY, kSlotsPerCopy * sizeof(cl_uint));
  packed_ = cl::Buffer(context_, CL_MEM_READ_WRITE, kSlotsPerCopy * cells * sizeof(Cell));
  packed_cells_ = cells;
}

void DeviceCellPool::write_slots(cl::CommandQueue& queue, const BgkMap& map, const std::vector<uint32_t>& slots,
                                 cl::Kernel& scatter) {
  const size_t cells = static_cast<size_t>(map.cells_per_block());
  if (slots.empty()) return;
  if (host_memory_) {
    in_mapped_range(queue, slots, cells * sizeof(Cell), CL_MAP_WRITE, [&](char* pool) {
      for (const uint32_t slot : slots)
        std::copy(map.block_cells(slot), map.block_cells(slot) + cells, reinterpret_cast<Cell*>(pool) + slot * cells);
    });
    return;
  }
  prepare_slot_copies(cells);
  for (size_t first = 0; first < slots.size(); first += kSlotsPerCopy) {
    const size_t count = std::min(kSlotsPerCopy, slots.size() - first);
    packed_host_.resize(count * cells);
    for (size_t i = 0; i < count; ++i)
      std::copy(map.block_cells(slots[first + i]), map.block_cells(slots[first + i]) + cells, &packed_host_[i * cells]);
    queue.enqueueWriteBuffer(slot_list_, CL_FALSE, 0, count * sizeof(cl_uint), &slots[first]);
    queue.enqueueWriteBuffer(packed_, CL_FALSE, 0, count * cells * sizeof(Cell), packed_host_.data());
    scatter.setArg(0, buffer_);
    scatter.setArg(1, slot_list_);
    scatter.setArg(2, packed_);
    queue.enqueueNDRangeKernel(scatter, cl::NullRange, cl::NDRange(cells, count));
    queue.finish();  // packed_host_ and the slot list are reused
  }
}

void DeviceCellPool::decay_slots(cl::CommandQueue& queue, const BgkMap& map, const std::vector<uint32_t>& slots,
                                 const std::vector<float>& factors, cl::Kernel& decay) {
  if (slots.empty()) return;
  // The lists copied into buffers made now (no wait for the queue); the queued kernel keeps them.
  const cl::Buffer slot_list(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, slots.size() * sizeof(cl_uint),
                             const_cast<uint32_t*>(slots.data()));
  const cl::Buffer factor_list(context_, CL_MEM_READ_ONLY | CL_MEM_COPY_HOST_PTR, factors.size() * sizeof(cl_float),
                               const_cast<float*>(factors.data()));
  decay.setArg(0, buffer_);
  decay.setArg(1, slot_list);
  decay.setArg(2, factor_list);
  decay.setArg(3, map.params().prior.alpha0);
  decay.setArg(4, map.params().prior.beta0);
  const size_t cells = static_cast<size_t>(map.cells_per_block());
  queue.enqueueNDRangeKernel(decay, cl::NullRange, cl::NDRange(cells, slots.size()));
}

void DeviceCellPool::read_slots(cl::CommandQueue& queue, BgkMap& map, const std::vector<uint32_t>& slots,
                                cl::Kernel& gather) {
  const size_t cells = static_cast<size_t>(map.cells_per_block());
  if (slots.empty()) return;
  if (host_memory_) {
    in_mapped_range(queue, slots, cells * sizeof(Cell), CL_MAP_READ, [&](char* pool) {
      const Cell* cells_of = reinterpret_cast<const Cell*>(pool);
      for (const uint32_t slot : slots)
        std::copy(cells_of + slot * cells, cells_of + (slot + 1) * cells, map.block_cells(slot));
    });
    return;
  }
  prepare_slot_copies(cells);
  for (size_t first = 0; first < slots.size(); first += kSlotsPerCopy) {
    const size_t count = std::min(kSlotsPerCopy, slots.size() - first);
    packed_host_.resize(count * cells);
    queue.enqueueWriteBuffer(slot_list_, CL_FALSE, 0, count * sizeof(cl_uint), &slots[first]);
    gather.setArg(0, buffer_);
    gather.setArg(1, slot_list_);
    gather.setArg(2, packed_);
    queue.enqueueNDRangeKernel(gather, cl::NullRange, cl::NDRange(cells, count));
    queue.enqueueReadBuffer(packed_, CL_TRUE, 0, count * cells * sizeof(Cell), packed_host_.data());
    for (size_t i = 0; i < count; ++i)
      std::copy(&packed_host_[i * cells], &packed_host_[(i + 1) * cells], map.block_cells(slots[first + i]));
  }
}

void DeviceCellPool::read_back(cl::CommandQueue& queue, BgkMap& map) const {
  if (slots_ == 0) return;
  const size_t slot_bytes = sizeof(Cell) * static_cast<size_t>(map.cells_per_block());
  queue.enqueueReadBuffer(buffer_, CL_TRUE, 0, slots_ * slot_bytes, map.cell_pool().data());
}

}  // namespace bgkmap::opencl_detail
