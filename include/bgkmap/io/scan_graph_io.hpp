// OctoMap scan graphs (.graph, liboctomap's binary ScanGraph format): one scan per node.
//
// Frames: a node stores its points in the sensor frame and the pose they were taken from. The
// reader applies the pose (liboctomap's own transform), so every Scan it returns is world-frame,
// with pose = the node pose and origin = the node position -- exactly what
// ScanGraph::readBinary followed by ScanGraph::transformScans gives. Its scans are marked
// Scan::points_in_world_frame, so PreprocessParams::apply_viewpoint (meant for sensor-frame PCD
// files) never applies the node pose a second time.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// Reads a .graph file one node at a time, so a graph of thousands of scans never sits in memory.
// Nodes are decoded with liboctomap's own record readers (the steps of ScanNode::readBinary,
// which ScanGraph::readBinary calls per node) and transformed with its Pose6D; the edge list
// (odometry constraints, unused for mapping) is checked but not decoded, which also avoids
// liboctomap's quadratic node lookup per edge.
class ScanGraphReader {
 public:
  // Opens `file` and checks its whole layout before any node is decoded: every node's point
  // count against the bytes left, the pose records (markers, finite values, unit quaternion),
  // the edge list (size, node ids) and the exact end of file. liboctomap trusts these counts
  // (it reserves what they claim), so anything that does not fit throws InputError naming the
  // file ("x.graph: scan graph node 3 claims 4294967295 points, only 1200 bytes left").
  explicit ScanGraphReader(const std::filesystem::path& file);

  size_t node_count() const { return point_counts_.size(); }

  // The next node as a world-frame scan; false after the last.
  bool next(Scan& scan);

 private:
  std::filesystem::path file_;
  std::ifstream in_;
  std::vector<uint32_t> point_counts_;  // per node, from the layout check
  size_t next_node_ = 0;
};

// All nodes of a graph file at once.
std::vector<Scan> read_scan_graph(const std::filesystem::path& file);

}  // namespace bgkmap
