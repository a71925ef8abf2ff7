// The memory limit: sizes as the command line gives them, and growth that stops short of the
// limit instead of running into it.
#include "bgkmap/core/memory_limit.hpp"

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "bgkmap/map/internal/cell_pool.hpp"

namespace bgkmap {
namespace {

constexpr uint64_t kMiB = 1024 * 1024;

// Sets the limit to what is resident now plus `headroom`, and restores the default afterwards.
class LimitAboveResident {
 public:
  explicit LimitAboveResident(uint64_t headroom) { set_memory_limit_bytes(resident_memory_bytes() + headroom); }
  ~LimitAboveResident() { set_memory_limit_bytes(0); }
};

TEST(MemoryLimit, SizesParseInBinaryUnitsAndBadOnesAreRefused) {
  EXPECT_EQ(parse_byte_size("123456"), 123456u);
  EXPECT_EQ(parse_byte_size("50M"), 50 * kMiB);
  EXPECT_EQ(parse_byte_size("50MB"), 50 * kMiB);
  EXPECT_EQ(parse_byte_size("50Mi"), 50 * kMiB);
  EXPECT_EQ(parse_byte_size("1.5g"), 3 * 512 * kMiB);
  EXPECT_EQ(parse_byte_size("500k"), 500u * 1024);
  for (const char* bad : {"", "M", "50X", "-5M", "0", "nan", "1e30T", "5 M"}) {
    try {
      parse_byte_size(bad);
      ADD_FAILURE() << bad;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("is not a memory size"), std::string::npos) << e.what();
    }
  }
  EXPECT_EQ(format_bytes(512), "512 B");
  EXPECT_EQ(format_bytes(1536), "1.5 KiB");
  EXPECT_EQ(format_bytes(3.0 * 1024 * kMiB), "3.0 GiB");
}

TEST(MemoryLimit, DefaultIsHalfThePhysicalMemoryAtMost) {
  ASSERT_GT(physical_memory_bytes(), 0u);
  ASSERT_GT(resident_memory_bytes(), 0u);
  EXPECT_LE(default_memory_limit_bytes(), physical_memory_bytes() / 2);
  EXPECT_EQ(memory_limit_bytes(), default_memory_limit_bytes());
  set_memory_limit_bytes(123 * kMiB);
  EXPECT_EQ(memory_limit_bytes(), 123 * kMiB);
  set_memory_limit_bytes(0);
  EXPECT_EQ(memory_limit_bytes(), default_memory_limit_bytes());
}

TEST(MemoryLimit, GrowthDoublesWhileItFitsThenTakesWhatIsLeftThenRefuses) {
  const LimitAboveResident limit(64 * kMiB);
  EXPECT_EQ(grown_capacity(1000, 1001, 8, "x", "y"), 2000u);  // far from the limit: doubles
  EXPECT_EQ(grown_capacity(1000, 900, 8, "x", "y"), 1000u);   // nothing to grow
  // Doubling 100 MiB would take 100 MiB more, beyond the 64 MiB headroom: the capacity grows by
  // what fits instead, still at least to what is needed.
  const size_t grown = grown_capacity(100 * kMiB, 100 * kMiB + 1, 1, "x", "y");
  EXPECT_GT(grown, 100 * kMiB + 1);
  EXPECT_LT(grown, 165 * kMiB);
  try {
    grown_capacity(0, 100 * kMiB, 1, "the test's array", "use less");
    FAIL() << "100 MiB fit a 64 MiB headroom";
  } catch (const MemoryLimitExceeded& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.find("the test's array needs 100.0 MiB more ("), 0u) << what;
    EXPECT_NE(what.find("beyond --max-memory"), std::string::npos) << what;
    EXPECT_NE(what.find(": use less"), std::string::npos) << what;
  }
}

// The map's pool refuses to grow past the limit and keeps what it held.
TEST(MemoryLimit, CellPoolRefusesToGrowPastTheLimitAndKeepsItsCells) {
  const LimitAboveResident limit(32 * kMiB);
  CellPool pool;
  pool.append(1000, Cell{1, 2});
  try {
    pool.append(64 * kMiB / sizeof(Cell), Cell{3, 4});  // 64 MiB of cells
    FAIL() << "64 MiB of cells fit a 32 MiB headroom";
  } catch (const MemoryLimitExceeded& e) {
    EXPECT_NE(std::string(e.what()).find("the map's cells"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--resolution"), std::string::npos) << e.what();
  }
  ASSERT_EQ(pool.size(), 1000u);
  EXPECT_EQ(pool[999].alpha, 1.0f);
  EXPECT_EQ(pool[999].beta, 2.0f);
}

}  // namespace
}  // namespace bgkmap
