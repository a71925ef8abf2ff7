#include "bgkmap/integrate/bucketing.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "core/key_table.hpp"

namespace bgkmap {

double point_box_dist2(const Vec3f& p, const Aabb& box) {
  const double pv[3] = {p.x, p.y, p.z};
  const double lo[3] = {box.min.x, box.min.y, box.min.z};
  const double hi[3] = {box.max.x, box.max.y, box.max.z};
  double d2 = 0;
  for (int i = 0; i < 3; ++i) {
    const double d = pv[i] < lo[i] ? lo[i] - pv[i] : (pv[i] > hi[i] ? pv[i] - hi[i] : 0.0);
    d2 += d * d;
  }
  return d2;
}

double segment_box_dist2(const Vec3f& a, const Vec3f& b, const Aabb& box) {
  // f(t) = dist^2(a + t v, box) is convex and piecewise quadratic in t, with breaks where a
  // coordinate crosses a face plane. Minimise the quadratic exactly on each piece.
  const double o[3] = {a.x, a.y, a.z};
  const double v[3] = {double(b.x) - a.x, double(b.y) - a.y, double(b.z) - a.z};
  const double lo[3] = {box.min.x, box.min.y, box.min.z};
  const double hi[3] = {box.max.x, box.max.y, box.max.z};
  double breaks[8];
  int n = 0;
  breaks[n++] = 0.0;
  breaks[n++] = 1.0;
  for (int i = 0; i < 3; ++i) {
    if (v[i] == 0) continue;
    for (const double plane : {lo[i], hi[i]}) {
      const double t = (plane - o[i]) / v[i];
      if (t > 0 && t < 1) breaks[n++] = t;
    }
  }
  for (int i = 1; i < n; ++i)  // insertion sort: at most 8 values
    for (int j = i; j > 0 && breaks[j - 1] > breaks[j]; --j) std::swap(breaks[j - 1], breaks[j]);
  auto f = [&](double t) {
    double d2 = 0;
    for (int i = 0; i < 3; ++i) {
      const double x = o[i] + t * v[i];
      const double d = x < lo[i] ? lo[i] - x : (x > hi[i] ? x - hi[i] : 0.0);
      d2 += d * d;
    }
    return d2;
  };
  double best = std::min(f(0.0), f(1.0));
  for (int k = 0; k + 1 < n; ++k) {
    const double t0 = breaks[k], t1 = breaks[k + 1];
    if (t1 <= t0) continue;
    const double tm = 0.5 * (t0 + t1);
    // On this piece each axis is either inside its slab or (x - plane)^2 for a fixed plane.
    double qa = 0, qb = 0;  // f(t) = qa t^2 + qb t + const
    for (int i = 0; i < 3; ++i) {
      const double x = o[i] + tm * v[i];
      double plane;
      if (x < lo[i]) plane = lo[i];
      else if (x > hi[i]) plane = hi[i];
      else continue;
      qa += v[i] * v[i];
      qb += 2 * v[i] * (o[i] - plane);
    }
    if (qa > 0) {
      const double t = std::clamp(-qb / (2 * qa), t0, t1);
      best = std::min(best, f(t));
    }
  }
  return best;
}

LocalHit make_local_hit(const Vec3d& c0, const Vec3f& h) {
  return {static_cast<float>(h.x - c0.x), static_cast<float>(h.y - c0.y), static_cast<float>(h.z - c0.z)};
}

namespace {

// Computed once per beam rather than once per (block, beam) pair.
using BeamLine = ScanBuckets::Scratch::BeamLine;

BeamLine beam_line(const Vec3f& origin, const Vec3f& free_end) {
  BeamLine line{{origin.x, origin.y, origin.z}, {0, 0, 0}, 0};
  const double v[3] = {double(free_end.x) - line.a[0], double(free_end.y) - line.a[1], double(free_end.z) - line.a[2]};
  line.length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (line.length > 0)
    for (int i = 0; i < 3; ++i) line.u[i] = v[i] / line.length;
  return line;
}

LocalBeam local_beam(const Vec3d& c0, const Vec3d& mid, const BeamLine& line) {
  const double* a = line.a;
  const double* u = line.u;
  double s0 = 0;
  if (line.length > 0)
    s0 = std::clamp((mid.x - a[0]) * u[0] + (mid.y - a[1]) * u[1] + (mid.z - a[2]) * u[2], 0.0, line.length);
  LocalBeam b;
  b.qx = static_cast<float>(a[0] + s0 * u[0] - c0.x);
  b.qy = static_cast<float>(a[1] + s0 * u[1] - c0.y);
  b.qz = static_cast<float>(a[2] + s0 * u[2] - c0.z);
  b.ux = static_cast<float>(u[0]);
  b.uy = static_cast<float>(u[1]);
  b.uz = static_cast<float>(u[2]);
  b.s_min = static_cast<float>(-s0);
  b.s_max = static_cast<float>(line.length - s0);
  return b;
}

}  // namespace

LocalBeam make_local_beam(const Vec3d& c0, const Vec3d& mid, const Vec3f& origin, const Vec3f& free_end) {
  return local_beam(c0, mid, beam_line(origin, free_end));
}

namespace {

// The blocks a scan can reach, as a box of block keys, so that their numbers can be kept in a
// dense array. Keys outside it (none when it was computed from the scan's extent) still work.
struct BlockWindow {
  int32_t x0 = 0, y0 = 0, z0 = 0;
  uint32_t nx = 0, ny = 0, nz = 0;  // all 0: no window

  size_t size() const { return size_t(nx) * ny * nz; }
  bool contains(const BlockKey& k) const {
    return uint32_t(k.x - x0) < nx && uint32_t(k.y - y0) < ny && uint32_t(k.z - z0) < nz;
  }
  // x fastest: the blocks a beam visits one after another along a row are neighbours here.
  size_t offset(const BlockKey& k) const {
    return (size_t(uint32_t(k.z - z0)) * ny + uint32_t(k.y - y0)) * nx + uint32_t(k.x - x0);
  }
  // The inverse of offset().
  uint32_t x_index(size_t at) const { return static_cast<uint32_t>(at % nx); }
  uint32_t y_index(size_t at) const { return static_cast<uint32_t>((at / nx) % ny); }
  BlockKey key_at(size_t at) const {
    return {x0 + static_cast<int32_t>(x_index(at)), y0 + static_cast<int32_t>(y_index(at)),
            z0 + static_cast<int32_t>(at / (size_t(nx) * ny))};
  }
};

// Numbers block keys in order of first appearance. Keys inside the window are looked up in a
// dense array (`dense`: all kEmpty between uses, which the destructor restores); others in a
// key_table (open addressing). Hashing spread a beam's neighbouring blocks over the table: its
// probes and key compares were a quarter of bucketing (perf, 1 thread).
class KeyNumbering {
 public:
  KeyNumbering(std::vector<BlockKey>& keys, std::vector<uint32_t>& table, std::vector<uint32_t>& dense,
               const BlockWindow& window)
      : keys_(keys), table_(table), dense_(dense), window_(window) {
    keys_.clear();
    if (dense_.size() < window_.size()) dense_.resize(window_.size(), kEmpty);
    // The size the last scan grew the table to: scans are alike, so it rarely grows again.
    key_table::reset(table_, std::max<size_t>(1024, table_.size()));
  }
  ~KeyNumbering() {
    for (const BlockKey& key : keys_)
      if (window_.contains(key)) dense_[window_.offset(key)] = kEmpty;
  }
  KeyNumbering(const KeyNumbering&) = delete;
  KeyNumbering& operator=(const KeyNumbering&) = delete;

  uint32_t index(const BlockKey& key) {
    const bool in_window = window_.contains(key);
    uint32_t& number = in_window ? dense_[window_.offset(key)] : table_[key_table::position(table_, keys_, key)];
    if (number != kEmpty) return number;
    number = static_cast<uint32_t>(keys_.size());
    keys_.push_back(key);
    if (!in_window) key_table::grow_for(table_, keys_, ++hashed_);  // `number` may move
    return static_cast<uint32_t>(keys_.size() - 1);
  }

 private:
  static constexpr uint32_t kEmpty = key_table::kEmpty;

  std::vector<BlockKey>& keys_;
  std::vector<uint32_t>& table_;
  std::vector<uint32_t>& dense_;
  const BlockWindow window_;
  size_t hashed_ = 0;  // keys in table_
};

// Dense arrays of all parts together stay within this many entries (64 MB); a scan whose window
// would take more hashes all its keys.
constexpr size_t kDenseEntriesBudget = size_t(1) << 24;

using PartPairs = ScanBuckets::Scratch::PartPairs;

// Threads worth starting for `count` items of about `per_thread` each: one per `per_thread`
// items, at most `threads`. Every parallel region costs a wake-up and a barrier (tens of
// microseconds with passive waiting, a scheduler time slice when a core is busy with another
// process), so the light loops (a few nanoseconds an item) stay on one thread for small scans.
constexpr size_t kHeavyItemsPerThread = 256;    // observations searched for their blocks
constexpr size_t kPairItemsPerThread = 4096;    // pairs given their block-frame geometry
constexpr size_t kLightItemsPerThread = 32768;  // keys and pairs counted, numbered or moved
int team_for(size_t count, int threads, size_t per_thread = kHeavyItemsPerThread) {
  return std::max(1, std::min<int>(threads, static_cast<int>(count / per_thread) + 1));
}

// How one kind of observation was split: `parts` contiguous ranges run on `team` threads.
struct PartSplit {
  int team = 1, parts = 1;
};

// Runs find(i, emit) for every observation i < count, where find calls emit(key) for each block
// that observation reaches. The observations are cut into contiguous parts (four per thread,
// taken dynamically, so a thread slowed by a busy core does not hold the others up); each part
// numbers the blocks it finds locally and keeps its pairs in input order.
template <class Find>
PartSplit find_pairs(size_t count, int threads, const BlockWindow& window, std::vector<PartPairs>& parts,
                     const Find& find) {
  PartSplit split;
  split.team = team_for(count, threads);
  split.parts = split.team == 1 ? 1 : 4 * split.team;
  if (parts.size() < static_cast<size_t>(split.parts)) parts.resize(static_cast<size_t>(split.parts));
  // A quarter of the budget for each kind's parts, half for the global numbering.
  const BlockWindow dense = window.size() * split.parts <= kDenseEntriesBudget / 4 ? window : BlockWindow{};
  const int64_t n = static_cast<int64_t>(count);
#pragma omp parallel for num_threads(split.team) schedule(dynamic, 1)
  for (int t = 0; t < split.parts; ++t) {
    PartPairs& mine = parts[static_cast<size_t>(t)];
    KeyNumbering local(mine.keys, mine.table, mine.dense, dense);
    mine.pairs.clear();
    for (int64_t i = n * t / split.parts; i < n * (t + 1) / split.parts; ++i) {
      const uint32_t obs = static_cast<uint32_t>(i);
      find(obs, [&](const BlockKey& key) { mine.pairs.emplace_back(local.index(key), obs); });
    }
  }
  return split;
}

// Global block numbers for the locally numbered blocks of the parts, in part order, so that
// blocks are numbered in order of first appearance in the concatenated pairs.
void number_globally(std::vector<PartPairs>& parts, const PartSplit& split, KeyNumbering& global) {
  for (int t = 0; t < split.parts; ++t) {
    PartPairs& part = parts[static_cast<size_t>(t)];
    part.to_global.resize(part.keys.size());
    for (size_t k = 0; k < part.keys.size(); ++k) part.to_global[k] = global.index(part.keys[k]);
  }
}

// With a window: every block any part of either kind found, numbered in key order, so that the
// blocks need no sort afterwards, and each part's local numbers mapped to those, both in
// parallel. (number_globally and the sort are serial: with them, bucketing 300 campus scans on
// 16 threads took 4.1 s, without 3.0-3.5 s.)
// `dense` is all kEmpty before and after.
void number_in_key_order(std::vector<PartPairs>& hit_parts, const PartSplit& hit_split,
                         std::vector<PartPairs>& beam_parts, const PartSplit& beam_split, const BlockWindow& window,
                         std::vector<uint32_t>& dense, std::vector<uint32_t>& present, std::vector<BlockKey>& keys) {
  if (dense.size() < window.size()) dense.resize(window.size(), key_table::kEmpty);
  std::vector<PartPairs*> parts;
  for (int t = 0; t < hit_split.parts; ++t) parts.push_back(&hit_parts[static_cast<size_t>(t)]);
  for (int t = 0; t < beam_split.parts; ++t) parts.push_back(&beam_parts[static_cast<size_t>(t)]);
  size_t found = 0;
  for (const PartPairs* part : parts) found += part->keys.size();
  const int team = team_for(found, std::max(hit_split.team, beam_split.team), kLightItemsPerThread);
  const int64_t part_count = static_cast<int64_t>(parts.size());
  // Mark: parts finding the same block write the same value (atomic, so that is no data race).
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int64_t t = 0; t < part_count; ++t)
    for (const BlockKey& key : parts[static_cast<size_t>(t)]->keys)
      __atomic_store_n(&dense[window.offset(key)], 0u, __ATOMIC_RELAXED);
  // The marked offsets in memory order (z, y, x), then stable counting sorts by y and by x give
  // key order (x, y, z).
  present.clear();
  for (size_t at = 0; at < window.size(); ++at)
    if (dense[at] != key_table::kEmpty) present.push_back(static_cast<uint32_t>(at));
  std::vector<uint32_t> by_y(present.size());
  auto counting_sort = [&](const std::vector<uint32_t>& from, std::vector<uint32_t>& to, uint32_t buckets,
                           auto bucket_of) {
    std::vector<uint32_t> start(buckets + 1, 0);
    for (uint32_t at : from) ++start[bucket_of(at) + 1];
    for (uint32_t b = 0; b < buckets; ++b) start[b + 1] += start[b];
    for (uint32_t at : from) to[start[bucket_of(at)]++] = at;
  };
  counting_sort(present, by_y, window.ny, [&](uint32_t at) { return window.y_index(at); });
  counting_sort(by_y, present, window.nx, [&](uint32_t at) { return window.x_index(at); });
  keys.resize(present.size());
  for (uint32_t number = 0; number < present.size(); ++number) {
    dense[present[number]] = number;
    keys[number] = window.key_at(present[number]);
  }
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int64_t t = 0; t < part_count; ++t) {
    PartPairs& part = *parts[static_cast<size_t>(t)];
    part.to_global.resize(part.keys.size());
    for (size_t k = 0; k < part.keys.size(); ++k) part.to_global[k] = dense[window.offset(part.keys[k])];
  }
  for (uint32_t at : present) dense[at] = key_table::kEmpty;
}

// Writes the observation ids of one kind grouped by block (CSR ranges through the members):
// a counting sort whose counts and placement run per part, in parallel. Within a block, part
// t's pairs follow those of the parts before it, and each part's are in input order, so the
// result is the same as sorting the concatenated pairs stably.
void scatter(std::vector<PartPairs>& parts, const PartSplit& split, std::vector<BlockWork>& blocks,
             std::vector<uint32_t>& ids, uint32_t BlockWork::*begin, uint32_t BlockWork::*count) {
  size_t pairs = 0;
  for (int t = 0; t < split.parts; ++t) pairs += parts[static_cast<size_t>(t)].pairs.size();
  const int part_count = split.parts, team = team_for(pairs, split.team, kLightItemsPerThread);
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int t = 0; t < part_count; ++t) {
    PartPairs& part = parts[static_cast<size_t>(t)];
    part.cursor.assign(blocks.size(), 0);
    for (const auto& [local, obs] : part.pairs) ++part.cursor[part.to_global[local]];
  }
  // Each block's range, then each part's start in it, in parallel over blocks: only the prefix
  // over blocks stays serial (serial blocks x parts steps grow with the threads: 64 parts on 16).
  const int64_t block_count = static_cast<int64_t>(blocks.size());
#pragma omp parallel for num_threads(team) schedule(static)
  for (int64_t b = 0; b < block_count; ++b) {
    uint32_t n = 0;
    for (int t = 0; t < part_count; ++t) n += parts[static_cast<size_t>(t)].cursor[static_cast<size_t>(b)];
    blocks[static_cast<size_t>(b)].*count = n;
  }
  uint32_t offset = 0;
  for (BlockWork& block : blocks) {
    block.*begin = offset;
    offset += block.*count;
  }
#pragma omp parallel for num_threads(team) schedule(static)
  for (int64_t b = 0; b < block_count; ++b) {
    uint32_t at = blocks[static_cast<size_t>(b)].*begin;
    for (int t = 0; t < part_count; ++t) {
      uint32_t& cursor = parts[static_cast<size_t>(t)].cursor[static_cast<size_t>(b)];
      const uint32_t n = cursor;
      cursor = at;
      at += n;
    }
  }
  ids.resize(offset);
#pragma omp parallel for num_threads(team) schedule(dynamic, 1)
  for (int t = 0; t < part_count; ++t) {
    PartPairs& part = parts[static_cast<size_t>(t)];
    for (const auto& [local, obs] : part.pairs) ids[part.cursor[part.to_global[local]]++] = obs;
  }
}

}  // namespace

void bucket_scan(const Grid& grid, float support_radius_m, const ScanObservations& obs, ScanBuckets& out,
                 int threads) {
  // Only the blocks start empty. The id and geometry arrays are resized below and every element
  // is written; keeping the last scan's sizes spares zero-filling tens of MB per scan in one thread.
  out.blocks.clear();
  ScanBuckets::Scratch& scratch = out.scratch;
  const double r = support_radius_m;
  const double r2 = r * r;
  const double bs = grid.block_size();

  // Blocks along one axis whose cell-centre interval, grown by r, meets [lo, hi]: block k's
  // centres span [k bs + h, (k+1) bs - h], h = half a cell. Padded by a hair: the exact distance
  // test below decides.
  const double h = 0.5 * grid.resolution();
  const double pad = 1e-9 * bs;
  auto block_span = [&](double lo, double hi, int32_t& k0, int32_t& k1) {
    k0 = static_cast<int32_t>(std::ceil((lo + h - r - pad) / bs - 1.0));
    k1 = static_cast<int32_t>(std::floor((hi - h + r + pad) / bs));
    return k0 <= k1;
  };

  // The blocks within reach of the scan's extent (origin, hits and beam ends), padded by one
  // block against rounding: every key found below lies inside.
  BlockWindow window;
  {
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
      spans = block_span(lo[ax], hi[ax], k0[ax], k1[ax]);
      extent *= double(k1[ax]) - double(k0[ax]) + 3;
    }
    if (spans && extent <= double(kDenseEntriesBudget / 2))
      window = {k0[0] - 1, k0[1] - 1, k0[2] - 1, uint32_t(k1[0] - k0[0] + 3), uint32_t(k1[1] - k0[1] + 3),
                uint32_t(k1[2] - k0[2] + 3)};
  }

  // Hits and beams are independent; find_pairs cuts each into parts, and grouping the parts'
  // pairs in part order gives each block its observations in input order whatever the threads.
  const PartSplit hit_split = find_pairs(obs.hits.size(), threads, window, scratch.hits, [&](uint32_t i, const auto& emit) {
    const Vec3f& p = obs.hits[i];
    int32_t x0, x1, y0, y1, z0, z1;
    if (!block_span(p.x, p.x, x0, x1) || !block_span(p.y, p.y, y0, y1) || !block_span(p.z, p.z, z0, z1)) return;
    for (int32_t z = z0; z <= z1; ++z)
      for (int32_t y = y0; y <= y1; ++y)
        for (int32_t x = x0; x <= x1; ++x) {
          const BlockKey k{x, y, z};
          if (point_box_dist2(p, grid.block_center_box(k)) < r2) emit(k);
        }
  });

  // Beams: per z-slab of blocks, clip the segment to the slab's reach, then per row of blocks
  // clip again; the x range of what is left gives the candidate blocks of that row, and those
  // within reach are one run of them, whose ends are searched for. Every block is emitted at
  // most once, so no deduplication is needed. A candidate is accepted at once when
  // the segment passes through the block's cell-centre box grown by r along one axis only (every
  // point there is within r of the box); only the rest, which pass near an edge or corner, pay
  // for the exact segment-box distance.
  const double o[3] = {obs.origin.x, obs.origin.y, obs.origin.z};
  struct Span {  // parameters t of o + t v on one axis inside a block's slab
    double t0, t1;
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  // The slab of block k on axis `ax`: its cell centres' interval (inner) and that grown by r (reach).
  auto slab_span = [&](const double* v, const double* inv_v, int ax, double lo, double hi) -> Span {
    if (v[ax] == 0) return (o[ax] >= lo && o[ax] <= hi) ? Span{-kInf, kInf} : Span{kInf, -kInf};
    const double ta = (lo - o[ax]) * inv_v[ax], tb = (hi - o[ax]) * inv_v[ax];
    return ta < tb ? Span{ta, tb} : Span{tb, ta};
  };
  auto inner_span = [&](const double* v, const double* inv_v, int ax, int32_t k) {
    return slab_span(v, inv_v, ax, k * bs + h, (k + 1) * bs - h);
  };
  auto reach_span = [&](const double* v, const double* inv_v, int ax, int32_t k) {
    return slab_span(v, inv_v, ax, k * bs + h - r - pad, (k + 1) * bs - h + r + pad);
  };
  auto meets = [](const Span& a, const Span& b, const Span& c) {  // within t in [0, 1]
    return std::max({0.0, a.t0, b.t0, c.t0}) <= std::min({1.0, a.t1, b.t1, c.t1});
  };
  // Exact test for the candidates the face test leaves (the segment passes the block near an
  // edge or corner): the squared distance from o + t v to the block's cell-centre box, minimised
  // over the t where the segment is inside the grown box (elsewhere it is farther than r). In
  // t-space an axis that moves contributes v_a^2 (t - clamp(t, inner_a))^2, so the distance is a
  // convex piecewise quadratic with breaks at the inner spans' ends; its slope is found to change
  // sign between two neighbouring breaks, where it is linear. The same decisions as
  // segment_box_dist2 (tests/test_bucketing.cpp compares them) at a fraction of its cost.
  auto within_reach = [&](const double* v, const Span* inner, const Span* reach, const int32_t* key) {
    const double t_lo = std::max({0.0, reach[0].t0, reach[1].t0, reach[2].t0});
    const double t_hi = std::min({1.0, reach[0].t1, reach[1].t1, reach[2].t1});
    if (t_lo > t_hi) return false;
    double still = 0;  // axes along which the segment does not move: a constant distance
    double w[3], i0[3], i1[3];
    int moving = 0;
    for (int ax = 0; ax < 3; ++ax) {
      if (v[ax] == 0) {
        const double lo = key[ax] * bs + h, hi = (key[ax] + 1) * bs - h;
        const double e = o[ax] < lo ? lo - o[ax] : (o[ax] > hi ? o[ax] - hi : 0.0);
        still += e * e;
      } else {
        w[moving] = v[ax] * v[ax];
        i0[moving] = inner[ax].t0;
        i1[moving] = inner[ax].t1;
        ++moving;
      }
    }
    auto slope = [&](double t) {  // half the derivative
      double sum = 0;
      for (int m = 0; m < moving; ++m) sum += w[m] * (t - std::clamp(t, i0[m], i1[m]));
      return sum;
    };
    double t = t_lo;
    const double s_lo = slope(t_lo);
    if (s_lo < 0) {
      const double s_hi = slope(t_hi);
      if (s_hi <= 0) {
        t = t_hi;
      } else {
        double left = t_lo, s_left = s_lo, right = t_hi, s_right = s_hi;
        for (int m = 0; m < moving; ++m)
          for (const double p : {i0[m], i1[m]}) {
            if (!(p > left && p < right)) continue;
            const double sp = slope(p);
            if (sp < 0) {
              left = p;
              s_left = sp;
            } else if (sp > 0) {
              right = p;
              s_right = sp;
            } else {
              left = right = p;
            }
          }
        t = left == right ? left : left - s_left * (right - left) / (s_right - s_left);
      }
    }
    double d2 = still;
    for (int m = 0; m < moving; ++m) {
      const double e = t - std::clamp(t, i0[m], i1[m]);
      d2 += w[m] * e * e;
    }
    return d2 < r2;
  };
  const PartSplit beam_split = find_pairs(obs.free_ends.size(), threads, window, scratch.beams, [&](uint32_t i, const auto& emit) {
      const Vec3f& b = obs.free_ends[i];
      const double v[3] = {double(b.x) - o[0], double(b.y) - o[1], double(b.z) - o[2]};
      const double inv_v[3] = {v[0] != 0 ? 1 / v[0] : 0.0, v[1] != 0 ? 1 / v[1] : 0.0, v[2] != 0 ? 1 / v[2] : 0.0};
      int32_t z0, z1;
      if (!block_span(std::min(o[2], o[2] + v[2]), std::max(o[2], o[2] + v[2]), z0, z1)) return;
      for (int32_t z = z0; z <= z1; ++z) {
        const Span gz = reach_span(v, inv_v, 2, z), iz = inner_span(v, inv_v, 2, z);
        const double tz0 = std::max(0.0, gz.t0), tz1 = std::min(1.0, gz.t1);
        if (tz0 > tz1) continue;
        int32_t y0, y1;
        const double ya = o[1] + tz0 * v[1], yb = o[1] + tz1 * v[1];
        if (!block_span(std::min(ya, yb), std::max(ya, yb), y0, y1)) continue;
        for (int32_t y = y0; y <= y1; ++y) {
          const Span gy = reach_span(v, inv_v, 1, y), iy = inner_span(v, inv_v, 1, y);
          const double t0 = std::max(tz0, gy.t0), t1 = std::min(tz1, gy.t1);
          if (t0 > t1) continue;
          int32_t x0, x1;
          const double xa = o[0] + t0 * v[0], xb = o[0] + t1 * v[0];
          if (!block_span(std::min(xa, xb), std::max(xa, xb), x0, x1)) continue;
          auto reaches = [&](int32_t x) {
            const Span gx = reach_span(v, inv_v, 0, x), ix = inner_span(v, inv_v, 0, x);
            const Span inner[3] = {ix, iy, iz}, reach[3] = {gx, gy, gz};
            const int32_t key[3] = {x, y, z};
            return meets(ix, iy, gz) || meets(ix, gy, iz) || meets(gx, iy, iz) || within_reach(v, inner, reach, key);
          };
          // The distance from the segment to block x's box is convex in x (the distance from a
          // point moving along a line to a convex set), so the blocks within reach are one run:
          // only its ends are searched for, from both sides (on the campus scans 23 % fewer tests).
          while (x0 <= x1 && !reaches(x0)) ++x0;
          while (x1 > x0 && !reaches(x1)) --x1;
          for (int32_t x = x0; x <= x1; ++x) emit(BlockKey{x, y, z});
        }
      }
  });
  // Blocks in key order (deterministic, whatever order they were first seen in).
  const bool in_key_order = window.size() > 0;
  if (in_key_order) {
    number_in_key_order(scratch.hits, hit_split, scratch.beams, beam_split, window, scratch.dense, scratch.order,
                        scratch.keys);
  } else {
    KeyNumbering global(scratch.keys, scratch.table, scratch.dense, window);
    number_globally(scratch.hits, hit_split, global);
    number_globally(scratch.beams, beam_split, global);
  }
  out.blocks.resize(scratch.keys.size());
  for (size_t b = 0; b < scratch.keys.size(); ++b) out.blocks[b].key = scratch.keys[b];
  scatter(scratch.hits, hit_split, out.blocks, out.hit_ids, &BlockWork::hit_begin, &BlockWork::hit_count);
  scatter(scratch.beams, beam_split, out.blocks, out.beam_ids, &BlockWork::beam_begin, &BlockWork::beam_count);
  if (!in_key_order) {
    std::vector<uint32_t>& order = scratch.order;
    order.resize(out.blocks.size());
    for (uint32_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](uint32_t x, uint32_t y) { return out.blocks[x].key < out.blocks[y].key; });
    std::vector<BlockWork>& sorted = scratch.sorted;
    sorted.clear();
    for (uint32_t k : order) sorted.push_back(out.blocks[k]);
    out.blocks.swap(sorted);
  }

  // Each pair's geometry in its block's frame.
  out.hits.resize(out.hit_ids.size());
  out.beams.resize(out.beam_ids.size());
  std::vector<BeamLine>& lines = scratch.lines;
  lines.resize(obs.free_ends.size());
  const int64_t beam_count = static_cast<int64_t>(obs.free_ends.size());
#pragma omp parallel for num_threads(team_for(lines.size(), beam_split.team, kLightItemsPerThread)) schedule(static)
  for (int64_t beam = 0; beam < beam_count; ++beam)
    lines[static_cast<size_t>(beam)] = beam_line(obs.origin, obs.free_ends[static_cast<size_t>(beam)]);
  const double mid_offset = 0.5 * (grid.cells_per_side() - 1) * grid.resolution();
  const int64_t block_count = static_cast<int64_t>(out.blocks.size());
#pragma omp parallel for num_threads(team_for(out.hit_ids.size() + out.beam_ids.size(), threads, kPairItemsPerThread)) \
    schedule(dynamic, 16)
  for (int64_t b = 0; b < block_count; ++b) {
    const BlockWork& w = out.blocks[static_cast<size_t>(b)];
    const Vec3d c0 = grid.block_first_center_d(w.key);
    const Vec3d mid{c0.x + mid_offset, c0.y + mid_offset, c0.z + mid_offset};
    for (uint32_t k = w.hit_begin; k < w.hit_begin + w.hit_count; ++k)
      out.hits[k] = make_local_hit(c0, obs.hits[out.hit_ids[k]]);
    for (uint32_t k = w.beam_begin; k < w.beam_begin + w.beam_count; ++k)
      out.beams[k] = local_beam(c0, mid, lines[out.beam_ids[k]]);
  }
}

void keep_layer_blocks(ScanBuckets& buckets, int32_t block_z) {
  std::vector<BlockWork>& blocks = buckets.blocks;
  blocks.erase(std::remove_if(blocks.begin(), blocks.end(), [&](const BlockWork& w) { return w.key.z != block_z; }),
               blocks.end());
}

}  // namespace bgkmap
