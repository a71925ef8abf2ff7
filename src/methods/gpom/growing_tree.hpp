// gpom's k-d trees: nanoflann over the points of every scan so far, found k nearest at a time.
#pragma once

#include <nanoflann.hpp>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap::gpom {

// nanoflann's dataset adaptor over a growing vector of points.
struct PointCloud {
  std::vector<Vec3f> points;
  size_t kdtree_get_point_count() const { return points.size(); }
  float kdtree_get_pt(size_t i, size_t dim) const {
    const Vec3f& p = points[i];
    return dim == 0 ? p.x : (dim == 1 ? p.y : p.z);
  }
  template <class Box>
  bool kdtree_get_bbox(Box&) const { return false; }
};
using PointTree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, PointCloud>, PointCloud, 3,
                                                      uint32_t>;

// A k-d tree over points appended scan by scan, rebuilt (one static tree searches faster than
// nanoflann's dynamic forest) when it is next searched after points came.
class GrowingTree {
 public:
  GrowingTree() = default;
  // A copy holds the points; its tree is built when it is next searched (the tree refers to its
  // own cloud, so it is neither copied nor moved).
  GrowingTree(const GrowingTree& other) : cloud_(other.cloud_) {}
  GrowingTree& operator=(const GrowingTree&) = delete;
  void add(const std::vector<Vec3f>& points) { cloud_.points.insert(cloud_.points.end(), points.begin(), points.end()); }
  void build() {
    if (tree_ && built_size_ == cloud_.points.size()) return;
    tree_ = std::make_unique<PointTree>(3, cloud_, nanoflann::KDTreeSingleIndexAdaptorParams(16));
    tree_->buildIndex();
    built_size_ = cloud_.points.size();
    build_count_ = next_build_count();
  }
  size_t size() const { return cloud_.points.size(); }
  size_t capacity() const { return cloud_.points.capacity(); }
  const Vec3f& operator[](size_t i) const { return cloud_.points[i]; }
  // The (up to) k nearest points, nearest first: ids and squared distances. After build().
  // Queries come cell by cell, so the calling thread's previous search of this tree for k bounds
  // this one: its k nearest lie within (its k-th distance + |q - q_prev|) of q, and a search
  // that starts from that radius prunes from its first leaf. The result is the unbounded
  // search's (the same points visited in the same order, fewer branches); a bound that finds
  // fewer than k (rounding) repeats the search unbounded.
  size_t nearest(const Vec3d& q, size_t k, std::vector<uint32_t>& ids, std::vector<float>& d2) const {
    ids.resize(k);
    d2.resize(k);
    const float query[3] = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z)};
    size_t found = 0;
    if (!cloud_.points.empty()) {
      // A few trees and k per thread (gpom searches two trees with two k per query).
      thread_local PreviousSearch previous[4];
      thread_local unsigned replaced = 0;
      PreviousSearch* last = nullptr;
      for (PreviousSearch& p : previous)
        if (p.tree == this && p.build == build_count_ && p.k == k) last = &p;
      if (last && k <= cloud_.points.size()) {
        const double dx = q.x - last->q.x, dy = q.y - last->q.y, dz = q.z - last->q.z;
        const float radius = static_cast<float>((std::sqrt(double(last->kth_d2)) + std::sqrt(dx * dx + dy * dy + dz * dz)) *
                                                    (1 + 1e-5) + 1e-6);
        found = search(query, k, radius * radius, ids, d2);
      }
      if (!last) last = &previous[replaced++ % 4];
      if (found < std::min(k, cloud_.points.size())) found = search(query, k, std::numeric_limits<float>::max(), ids, d2);
      *last = {found == k ? this : nullptr, build_count_, k, q, found == k ? d2[k - 1] : 0.0f};
    }
    ids.resize(found);
    d2.resize(found);
    return found;
  }

 private:
  struct PreviousSearch {
    const GrowingTree* tree = nullptr;
    uint64_t build = 0;
    size_t k = 0;
    Vec3d q;
    float kth_d2 = 0;
  };

  // The k nearest within sqrt(worst_d2) (all of them when it is the float maximum).
  size_t search(const float query[3], size_t k, float worst_d2, std::vector<uint32_t>& ids, std::vector<float>& d2) const {
    nanoflann::KNNResultSet<float, uint32_t> result(k);
    result.init(ids.data(), d2.data());
    d2[k - 1] = worst_d2;  // the result set's initial worst distance: the search's starting radius
    tree_->findNeighbors(result, query, nanoflann::SearchParams());
    return result.size();
  }

  PointCloud cloud_;  // the tree keeps a reference to it
  std::unique_ptr<PointTree> tree_;
  size_t built_size_ = 0;
  uint64_t build_count_ = 0;  // which build of which tree a thread's previous search used
  static uint64_t next_build_count() {
    static std::atomic<uint64_t> count{0};
    return ++count;
  }
};

}  // namespace bgkmap::gpom
