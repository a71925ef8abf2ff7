#include "methods/gpom/first_scans_sample.hpp"

#include <algorithm>
#include <numeric>
#include <utility>
#include <vector>

#include "core/splitmix.hpp"

namespace bgkmap::gpom {

namespace {

// k distinct indices of [0, n) by a partial Fisher-Yates shuffle (all n when k >= n).
std::vector<uint32_t> draw_distinct(size_t n, size_t k, uint64_t& counter) {
  std::vector<uint32_t> ids(n);
  std::iota(ids.begin(), ids.end(), 0u);
  k = std::min(k, n);
  for (size_t i = 0; i < k; ++i) {
    const size_t j = i + static_cast<size_t>(unit_interval(splitmix64(counter++)) * double(n - i));
    std::swap(ids[i], ids[std::min(j, n - 1)]);
  }
  ids.resize(k);
  return ids;
}

}  // namespace

LocalModel first_scans_sample(const TrainingData& set, const FirstScans& first, size_t points, uint64_t seed) {
  uint64_t counter = seed * 1000003 + 11;
  LocalModel model;
  for (const uint32_t id : draw_distinct(first.hits, (points + 1) / 2, counter)) {
    model.train.push_back(to_d(set.hits[id]));
    model.labels.push_back(1.0);
  }
  for (const uint32_t beam : draw_distinct(first.beams, points / 2, counter)) {
    model.train.push_back(point_on_beam(set, beam, unit_interval(splitmix64(counter++))));
    model.labels.push_back(-1.0);
  }
  return model;
}

}  // namespace bgkmap::gpom
