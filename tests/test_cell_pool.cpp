// CellPool: the map's contiguous cell array, grown in place by remapping.
#include "bgkmap/map/internal/cell_pool.hpp"

#include <gtest/gtest.h>

#include <utility>

namespace bgkmap {
namespace {

// Cell i of block b holds (b, i): any cell moved, lost or overwritten by a growth shows.
void append_block(CellPool& pool, int block, int cells) {
  const size_t first = pool.size();
  pool.append(static_cast<size_t>(cells), Cell{0.5f, 0.25f});
  for (int i = 0; i < cells; ++i) {
    EXPECT_EQ(pool[first + i].alpha, 0.5f);
    EXPECT_EQ(pool[first + i].beta, 0.25f);
    pool[first + i] = Cell{static_cast<float>(block), static_cast<float>(i)};
  }
}

void expect_blocks(const CellPool& pool, int blocks, int cells) {
  ASSERT_EQ(pool.size(), static_cast<size_t>(blocks) * cells);
  for (int b = 0; b < blocks; ++b)
    for (int i = 0; i < cells; ++i) {
      const Cell& c = pool[static_cast<size_t>(b) * cells + i];
      ASSERT_EQ(c.alpha, static_cast<float>(b)) << b << " " << i;
      ASSERT_EQ(c.beta, static_cast<float>(i)) << b << " " << i;
    }
}

TEST(CellPool, GrowingKeepsEveryCell) {
  // 3000 blocks of 512 cells (12 MB): many remaps, across page and huge-page sizes.
  CellPool pool;
  EXPECT_TRUE(pool.empty());
  for (int b = 0; b < 3000; ++b) append_block(pool, b, 512);
  expect_blocks(pool, 3000, 512);
  // Odd block sizes (depth 3: 64 cells, here 27) never straddle wrongly.
  CellPool odd;
  for (int b = 0; b < 1000; ++b) append_block(odd, b, 27);
  expect_blocks(odd, 1000, 27);
}

TEST(CellPool, CopiesAreDeepAndMovesTakeOver) {
  CellPool pool;
  for (int b = 0; b < 10; ++b) append_block(pool, b, 64);
  CellPool copy = pool;
  copy[0] = Cell{-1.0f, -1.0f};
  expect_blocks(pool, 10, 64);  // the original is untouched
  EXPECT_EQ(copy[0].alpha, -1.0f);
  CellPool assigned;
  assigned = pool;
  expect_blocks(assigned, 10, 64);
  CellPool moved = std::move(copy);
  EXPECT_EQ(moved.size(), pool.size());
  EXPECT_EQ(moved[0].alpha, -1.0f);
  EXPECT_EQ(copy.size(), 0u);  // NOLINT(bugprone-use-after-move): moved-from is empty by contract
  for (int b = 10; b < 20; ++b) append_block(moved, b, 64);  // growing after a move still works
  EXPECT_EQ(moved.size(), 20u * 64);
  moved.clear();
  EXPECT_TRUE(moved.empty());
}

}  // namespace
}  // namespace bgkmap
