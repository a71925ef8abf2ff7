// One block's cells as a .bgk of format version 3 stores them: per field (alpha, then beta) a
// bitmap of the cells whose value moved from the prior, itself stored sparsely, and only those
// values (layout in docs/FORMAT.md).
#pragma once

#include <cstddef>
#include <string>

#include "bgkmap/map/internal/cell_pool.hpp"

namespace bgkmap::io_detail {

// The shortest and the longest body a block of `cells_per_block` cells can have.
size_t min_block_body_bytes(size_t cells_per_block);
size_t max_block_body_bytes(size_t cells_per_block);

// Appends the body of a block's cells to `out`; returns its length.
size_t append_block_body(std::string& out, const Cell* cells, size_t cells_per_block, const Cell& prior);

// Sets a block's cells from its body (exactly `n` bytes); "" or what is wrong with the body.
std::string decode_block_body(const char* body, size_t n, Cell* cells, size_t cells_per_block, const Cell& prior);

}  // namespace bgkmap::io_detail
