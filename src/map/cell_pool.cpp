#include "bgkmap/map/internal/cell_pool.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cstring>
#include <new>
#include <string>
#include <utility>

#include "bgkmap/core/memory_limit.hpp"

namespace bgkmap {

namespace {

constexpr size_t kPage = 4096;

size_t mapping_bytes(size_t cells) { return (cells * sizeof(Cell) + kPage - 1) / kPage * kPage; }

Cell* map_cells(size_t cells) {
  void* p = mmap(nullptr, mapping_bytes(cells), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) throw std::bad_alloc();
  return static_cast<Cell*>(p);
}

}  // namespace

CellPool::CellPool(const CellPool& other) {
  if (other.size_ == 0) return;
  grow_to(other.size_);
  std::memcpy(cells_, other.cells_, other.size_ * sizeof(Cell));
  size_ = other.size_;
}

CellPool& CellPool::operator=(const CellPool& other) {
  if (this != &other) {
    CellPool copy(other);
    *this = std::move(copy);
  }
  return *this;
}

CellPool::CellPool(CellPool&& other) noexcept
    : cells_(other.cells_), size_(other.size_), capacity_(other.capacity_) {
  other.cells_ = nullptr;
  other.size_ = other.capacity_ = 0;
}

CellPool& CellPool::operator=(CellPool&& other) noexcept {
  if (this != &other) {
    release();
    cells_ = other.cells_;
    size_ = other.size_;
    capacity_ = other.capacity_;
    other.cells_ = nullptr;
    other.size_ = other.capacity_ = 0;
  }
  return *this;
}

CellPool::~CellPool() { release(); }

void CellPool::release() {
  if (cells_ != nullptr) munmap(cells_, mapping_bytes(capacity_));
  cells_ = nullptr;
  size_ = capacity_ = 0;
}

void CellPool::append(size_t count, const Cell& value) {
  if (size_ + count > capacity_) grow_to(size_ + count);
  std::fill(cells_ + size_, cells_ + size_ + count, value);
  size_ += count;
}

void CellPool::grow_to(size_t min_capacity) {
  // Geometric growth keeps the number of remaps logarithmic; a remap costs page-table moves,
  // not a copy of the cells.
  const size_t wanted =
      grown_capacity(capacity_, std::max(min_capacity, kPage / sizeof(Cell)), sizeof(Cell),
                     "the map's cells (" + format_bytes(double(size_ * sizeof(Cell))) + " so far)",
                     "give a coarser --resolution or a shorter --max-range (or raise --max-memory)");
  const size_t capacity = mapping_bytes(wanted) / sizeof(Cell);
  if (cells_ == nullptr) {
    cells_ = map_cells(capacity);
  } else {
#ifdef MREMAP_MAYMOVE
    void* p = mremap(cells_, mapping_bytes(capacity_), mapping_bytes(capacity), MREMAP_MAYMOVE);
    if (p == MAP_FAILED) throw std::bad_alloc();
    cells_ = static_cast<Cell*>(p);
#else
    Cell* fresh = map_cells(capacity);
    std::memcpy(fresh, cells_, size_ * sizeof(Cell));
    munmap(cells_, mapping_bytes(capacity_));
    cells_ = fresh;
#endif
  }
  capacity_ = capacity;
}

}  // namespace bgkmap
