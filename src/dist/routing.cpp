#include "bgkmap/dist/routing.hpp"

#include <algorithm>

namespace bgkmap {

void ObservationRouter::route(const Grid& grid, float support_radius_m, const ScanObservations& obs,
                              const SpatialPartition& partition, int threads, std::vector<std::vector<uint32_t>>& hits,
                              std::vector<std::vector<uint32_t>>& ends) {
  const size_t ranks = static_cast<size_t>(partition.ranks());
  hits.resize(ranks);
  ends.resize(ranks);
  for (size_t r = 0; r < ranks; ++r) hits[r].clear(), ends[r].clear();
  if (ranks == 1) {  // every observation reaches the block it lies in or passes: all go to rank 0
    hits[0].resize(obs.hits.size());
    ends[0].resize(obs.free_ends.size());
    for (uint32_t i = 0; i < hits[0].size(); ++i) hits[0][i] = i;
    for (uint32_t i = 0; i < ends[0].size(); ++i) ends[0][i] = i;
    return;
  }
  bucket_scan(grid, support_radius_m, obs, buckets_, threads);
  by_owner_.resize(ranks);
  for (auto& blocks : by_owner_) blocks.clear();
  for (uint32_t b = 0; b < buckets_.blocks.size(); ++b)
    by_owner_[static_cast<size_t>(partition.owner(buckets_.blocks[b].key))].push_back(b);
  // An observation in several blocks of one owner is sent once: owners are handled one after
  // another, so a mark equal to the owner means "already listed for it".
  hit_mark_.assign(obs.hits.size(), -1);
  end_mark_.assign(obs.free_ends.size(), -1);
  for (size_t r = 0; r < ranks; ++r) {
    const int owner = static_cast<int>(r);
    for (const uint32_t b : by_owner_[r]) {
      const BlockWork& w = buckets_.blocks[b];
      for (uint32_t k = w.hit_begin; k < w.hit_begin + w.hit_count; ++k) {
        const uint32_t id = buckets_.hit_ids[k];
        if (hit_mark_[id] != owner) hit_mark_[id] = owner, hits[r].push_back(id);
      }
      for (uint32_t k = w.beam_begin; k < w.beam_begin + w.beam_count; ++k) {
        const uint32_t id = buckets_.beam_ids[k];
        if (end_mark_[id] != owner) end_mark_[id] = owner, ends[r].push_back(id);
      }
    }
    std::sort(hits[r].begin(), hits[r].end());
    std::sort(ends[r].begin(), ends[r].end());
  }
}

void select_observations(const ScanObservations& obs, const std::vector<uint32_t>& hits,
                         const std::vector<uint32_t>& ends, ScanObservations& out) {
  out.origin = obs.origin;
  out.hits.resize(hits.size());
  out.free_ends.resize(ends.size());
  for (size_t i = 0; i < hits.size(); ++i) out.hits[i] = obs.hits[hits[i]];
  for (size_t i = 0; i < ends.size(); ++i) out.free_ends[i] = obs.free_ends[ends[i]];
}

}  // namespace bgkmap
