#include "integrate/block_window.hpp"

namespace bgkmap {

BlockWindow scan_window(const BlockReach& reach, const ScanObservations& obs, size_t max_blocks) {
  // A scan without observations reaches nothing (its origin may lie beyond the key range).
  if (obs.hits.empty() && obs.free_ends.empty()) return {};
  float lo[3] = {obs.origin.x, obs.origin.y, obs.origin.z}, hi[3] = {lo[0], lo[1], lo[2]};
  auto extend = [&](const std::vector<Vec3f>& points) {
    for (const Vec3f& p : points) {
      lo[0] = std::min(lo[0], p.x), hi[0] = std::max(hi[0], p.x);
      lo[1] = std::min(lo[1], p.y), hi[1] = std::max(hi[1], p.y);
      lo[2] = std::min(lo[2], p.z), hi[2] = std::max(hi[2], p.z);
    }
  };
  extend(obs.hits);
  extend(obs.free_ends);
  int32_t k0[3] = {0, 0, 0}, k1[3] = {0, 0, 0};
  bool spans = true;
  double extent = 1;  // blocks in the padded box, in double: far-flung scans must not overflow
  for (int ax = 0; ax < 3 && spans; ++ax) {
    spans = reach.span(lo[ax], hi[ax], k0[ax], k1[ax]);
    extent *= double(k1[ax]) - double(k0[ax]) + 3;
  }
  if (!spans || extent > double(max_blocks)) return {};
  return {k0[0] - 1, k0[1] - 1, k0[2] - 1, uint32_t(k1[0] - k0[0] + 3), uint32_t(k1[1] - k0[1] + 3),
          uint32_t(k1[2] - k0[2] + 3)};
}

}  // namespace bgkmap
