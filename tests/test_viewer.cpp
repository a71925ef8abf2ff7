// bgkmap view's level of detail: merge_to_cap against a plain grouping of the cells by their
// parent at each level, and the page's limits.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <random>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/viz/viewer.hpp"
#include "support/test_support.hpp"

namespace bgkmap::viz {
namespace {

using Key = std::tuple<int32_t, int32_t, int32_t>;

int32_t floor_div(int32_t v, int32_t d) { return v >= 0 ? v / d : -((-v + d - 1) / d); }

// The boxes at `level` by grouping: each cell (at its own level <= `level`) under the parent
// whose index is its finest-level index divided by 2^level, rounded down.
std::map<Key, ViewCell> grouped(const std::vector<ViewCell>& cells, int level) {
  std::map<Key, ViewCell> out;
  for (const ViewCell& c : cells) {
    const int32_t d = 1 << (level - c.level);
    const Key k{floor_div(c.x, d), floor_div(c.y, d), floor_div(c.z, d)};
    auto [it, fresh] = out.try_emplace(k, c);
    ViewCell& m = it->second;
    if (fresh) {
      std::tie(m.x, m.y, m.z) = k;
      m.level = static_cast<uint8_t>(level);
      continue;
    }
    m.probability = std::max(m.probability, c.probability);
    m.uncertain = m.uncertain && c.uncertain;
    m.occupied = m.occupied || c.occupied;
  }
  return out;
}

std::vector<ViewCell> random_cells(size_t n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int32_t> coord(-70, 70);
  std::uniform_real_distribution<float> p(0.5f, 1.0f);
  std::map<Key, ViewCell> unique;  // distinct cells, as a map holds them
  while (unique.size() < n) {
    ViewCell c{coord(rng), coord(rng), coord(rng) / 4, 0, p(rng), rng() % 3 == 0, rng() % 2 == 0};
    unique.emplace(Key{c.x, c.y, c.z}, c);
  }
  std::vector<ViewCell> cells;
  for (const auto& [k, c] : unique) cells.push_back(c);
  std::shuffle(cells.begin(), cells.end(), rng);
  return cells;
}

TEST(ViewerLevelOfDetail, MergeToCapEqualsGroupingByParentsAtTheFirstLevelUnderTheCap) {
  const std::vector<ViewCell> cells = random_cells(20000, 7);
  for (size_t cap : {size_t{20000}, size_t{15000}, size_t{3000}, size_t{200}, size_t{8}}) {
    ViewMap map;
    map.cells = cells;
    const int level = merge_to_cap(map, cap);
    ASSERT_LE(map.cells.size(), cap);
    if (level > 0) {
      EXPECT_GT(grouped(cells, level - 1).size(), cap) << "merged one level too far";
    }
    const std::map<Key, ViewCell> expected = grouped(cells, level);
    ASSERT_EQ(map.cells.size(), expected.size()) << "cap " << cap;
    for (const ViewCell& c : map.cells) {
      const auto it = expected.find(Key{c.x, c.y, c.z});
      ASSERT_NE(it, expected.end());
      EXPECT_EQ(c.level, level);
      EXPECT_EQ(c.probability, it->second.probability);
      EXPECT_EQ(c.uncertain, it->second.uncertain);
      EXPECT_EQ(c.occupied, it->second.occupied);
    }
  }
}

TEST(ViewerLevelOfDetail, TreeLeavesOfSeveralSizesMergeWithTheirNeighbours) {
  // OctoMap's pruned leaves come at levels above 0: a level-2 leaf and the level-0 cells inside
  // and beside its parent.
  std::vector<ViewCell> cells = {{-1, 0, 0, 2, 0.6f, false, false},  // cells -4..-1, 0..3, 0..3
                                 {-5, 1, 2, 0, 0.9f, true, true},    // inside the level-3 parent (-1, 0, 0)
                                 {-8, 7, 7, 0, 0.7f, true, false},   // too
                                 {0, 0, 0, 0, 0.8f, false, true}};   // parent (0, 0, 0)
  ViewMap map;
  map.cells = cells;
  EXPECT_EQ(merge_to_cap(map, 2), 3);
  ASSERT_EQ(map.cells.size(), 2u);
  const std::map<Key, ViewCell> expected = grouped(cells, 3);
  for (const ViewCell& c : map.cells) {
    const ViewCell& e = expected.at(Key{c.x, c.y, c.z});
    EXPECT_EQ(c.probability, e.probability);
    EXPECT_EQ(c.uncertain, e.uncertain);
    EXPECT_EQ(c.occupied, e.occupied);
  }
  EXPECT_EQ(expected.at(Key{-1, 0, 0}).probability, 0.9f);
  EXPECT_FALSE(expected.at(Key{-1, 0, 0}).uncertain);
}

TEST(ViewerLevelOfDetail, FitToCapKeepsOccupiedCellsThenTheMostProbable) {
  std::vector<ViewCell> cells = random_cells(20000, 11);
  for (size_t i = 0; i < 3000; ++i) cells[i].probability = 0.75f;  // ties at the bound
  std::vector<ViewCell> occupied, others;
  for (const ViewCell& c : cells) (c.occupied ? occupied : others).push_back(c);
  ASSERT_GT(occupied.size(), 5000u);

  ViewMap whole;
  whole.cells = cells;
  const ViewReduction none = fit_to_cap(whole, cells.size());
  EXPECT_EQ(none.level, 0);
  EXPECT_EQ(none.min_probability, kMinViewProbability);
  EXPECT_EQ(whole.cells.size(), cells.size());

  for (size_t cap : {size_t{19000}, occupied.size() + 1500, occupied.size()}) {
    ViewMap map;
    map.cells = cells;
    const ViewReduction r = fit_to_cap(map, cap);
    EXPECT_EQ(r.level, 0);
    ASSERT_LE(map.cells.size(), cap);
    // Kept: every occupied cell, and exactly the others at or above the bound.
    std::map<Key, const ViewCell*> kept;
    for (const ViewCell& c : map.cells) kept[Key{c.x, c.y, c.z}] = &c;
    for (const ViewCell& c : occupied) EXPECT_EQ(kept.count(Key{c.x, c.y, c.z}), 1u);
    size_t others_kept = 0;
    for (const ViewCell& c : others) {
      const bool in = kept.count(Key{c.x, c.y, c.z}) == 1;
      EXPECT_EQ(in, c.probability >= r.min_probability) << c.probability << " vs " << r.min_probability;
      others_kept += in;
    }
    EXPECT_EQ(occupied.size() + others_kept, map.cells.size());
    EXPECT_GT(r.min_probability, kMinViewProbability);
  }

  ViewMap map;
  map.occupied_threshold = 0.7f;
  map.cells = cells;
  const ViewReduction merged = fit_to_cap(map, 3000);
  EXPECT_GT(merged.level, 0);
  EXPECT_EQ(merged.min_probability, 0.7f);
  const std::map<Key, ViewCell> expected = grouped(occupied, merged.level);
  ASSERT_EQ(map.cells.size(), expected.size());
  for (const ViewCell& c : map.cells) EXPECT_EQ(c.probability, expected.at(Key{c.x, c.y, c.z}).probability);
}

TEST(ViewerPage, HoldsTheCountsAndRefusesAMapWiderThanItsOffsets) {
  const std::filesystem::path dir = testing::make_temp_dir("viewer");
  ViewMap map;
  map.source = "m.bgk";
  map.cells = random_cells(500, 3);
  const size_t occupied = std::count_if(map.cells.begin(), map.cells.end(), [](const ViewCell& c) { return c.occupied; });
  const ViewStats stats = write_view_html(dir / "m.html", map, 100);
  EXPECT_EQ(stats.map_cells, 500u);
  EXPECT_LE(stats.cells, 100u);
  std::ifstream in(dir / "m.html");
  const std::string page{std::istreambuf_iterator<char>(in), {}};
  EXPECT_EQ(stats.bytes, page.size());
  EXPECT_NE(page.find("\"map_cells\":500"), std::string::npos);
  EXPECT_NE(page.find("\"map_occupied\":" + std::to_string(occupied)), std::string::npos);
  EXPECT_NE(page.find("\"cells\":" + std::to_string(stats.cells)), std::string::npos);

  map.cells = {{0, 0, 0, 0, 0.9f, false, true}, {70000, 0, 0, 0, 0.9f, false, true}};
  try {
    write_view_html(dir / "wide.html", map);
    FAIL() << "a map 70,001 cells wide was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("wide.html"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "wide.html"));
  // Under a cap that merges its cells, a map as wide fits.
  map.cells.clear();
  for (int32_t x = 0; x <= 70000; x += 8750) map.cells.push_back({x, 0, 0, 0, 0.9f, false, true});
  const ViewStats merged = write_view_html(dir / "wide.html", map, 8);
  EXPECT_GT(merged.reduction.level, 0);
  EXPECT_LE(merged.cells, 8u);
  EXPECT_THROW(write_view_html(dir / "m.html", map, 7), std::invalid_argument);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::viz
