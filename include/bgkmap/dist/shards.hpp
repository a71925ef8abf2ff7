// A distributed build's map as the ranks leave it: per rank a shard (a native .bgk of the blocks
// it owns, and an order file giving the scan that created each of them) and a manifest naming
// the shards. Merging orders all blocks as one process would have created them (by creating scan,
// then key: one scan's blocks are created in key order), so the merged .bgk is byte for byte the
// file a single-process build writes.
#pragma once

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/core/progress.hpp"
#include "bgkmap/dist/partition.hpp"
#include "bgkmap/io/held_inputs.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/map/bgk_map.hpp"

namespace bgkmap {

// The order of the blocks in a distributed build's .bgk, the order one process creates them: by
// creating scan, then by key. The shards' merge and the ranks' file written together both use
// it, so that both give the single-process file byte for byte.
inline bool block_file_order(uint32_t scan_a, const BlockKey& key_a, uint32_t scan_b, const BlockKey& key_b) {
  return scan_a != scan_b ? scan_a < scan_b : key_a < key_b;
}

struct ShardManifest {
  int ranks = 0;
  uint64_t scans = 0;                    // scans mapped (global scan numbers 0 .. scans-1)
  std::vector<uint64_t> partition;       // first tile code of each rank (dist/partition.hpp)
  std::vector<std::string> shard_maps;   // per rank, relative to the manifest's folder
  std::vector<std::string> shard_orders;
  std::vector<HeldInput> held;           // the scans the map holds, as a single-process .bgk records them
};

// Shard file names for rank r in a shard folder: the final ones, or (checkpoint_scans > 0) those
// of the checkpoint holding that many scans.
std::string shard_map_name(int rank, uint64_t checkpoint_scans = 0);
std::string shard_order_name(int rank, uint64_t checkpoint_scans = 0);
// The manifest's name in a shard folder.
inline constexpr const char* kShardManifestName = "manifest.json";
// Where the ranks of a running build record their last step (one line per rank).
inline constexpr const char* kShardProgressName = "progress";

// Removes the checkpoint shards in a folder of fewer scans than `keep_scans` (0: all of them).
// Those of more scans stay: ranks that map ahead may be writing the next checkpoint already.
void remove_checkpoints(const std::filesystem::path& folder, uint64_t keep_scans);

// Writes a rank's shard atomically: the map and, per slot, the (global) scan that created it.
void write_shard(const std::filesystem::path& folder, int rank, const BgkMap& map,
                 const std::vector<uint32_t>& created_by_scan, uint64_t checkpoint_scans = 0);
// The order file of a shard; throws InputError naming the file when it is not one.
std::vector<uint32_t> read_shard_order(const std::filesystem::path& file);

// Throws InputError naming `file` unless every block of `shard` is in `rank`'s part of the
// partition (a shard of another rank, or of another run, would be read as this rank's).
void check_shard_blocks_owned(const BgkMap& shard, const SpatialPartition& partition, int rank,
                              const std::filesystem::path& file);

void write_manifest(const std::filesystem::path& file, const ShardManifest& manifest);
// Throws InputError naming the file when it is not a shard manifest.
ShardManifest read_manifest(const std::filesystem::path& file);

// The merged map of a manifest's shards (the manifest's path, or its folder), blocks in the
// order one process creates them. Throws InputError when a shard is missing, corrupt or does not
// agree with the others (parameters, a block in two shards). `progress` hears of the shards read
// and the blocks merged.
BgkMap merge_shards(const std::filesystem::path& manifest, ShardManifest* read = nullptr,
                    const ProgressCallback& progress = {});

// True when `path` names a shard manifest or a folder holding one.
bool is_shard_manifest(const std::filesystem::path& path);

// A native .bgk, or a shard folder (or its manifest) merged, with the scans it holds: what
// `bgkmap info` and `bgkmap eval` read.
NativeMapFile read_native_map_or_shards(const std::filesystem::path& path);

// A shard folder read one shard at a time: a point is looked up in the shard of the rank owning
// its block (the manifest's partition), read on first use; `bgkmap query` reads only the shards
// its points fall in.
class ShardedMapReader {
 public:
  explicit ShardedMapReader(const std::filesystem::path& manifest);
  // The shard holding the cell of (x, y, z) (all shards share the grid and parameters).
  const BgkMap& map_at(double x, double y, double z);

 private:
  std::filesystem::path folder_;
  ShardManifest manifest_;
  SpatialPartition partition_;
  std::vector<std::unique_ptr<BgkMap>> shards_;  // shard 0 read first: the grid
};

}  // namespace bgkmap
