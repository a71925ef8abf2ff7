#include "bgkmap/dist/shards.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/native_map.hpp"
#include "core/json_integer.hpp"
#include "core/progress_counter.hpp"

namespace bgkmap {

namespace {

constexpr char kOrderMagic[8] = {'B', 'G', 'K', 'O', 'R', 'D', '1', '\n'};

std::string numbered(int rank, uint64_t checkpoint_scans, const char* ext) {
  char name[80];
  if (checkpoint_scans == 0) std::snprintf(name, sizeof name, "rank-%04d%s", rank, ext);
  else std::snprintf(name, sizeof name, "rank-%04d.at-%09llu%s", rank, static_cast<unsigned long long>(checkpoint_scans), ext);
  return name;
}

std::filesystem::path manifest_file(const std::filesystem::path& path) {
  return std::filesystem::is_directory(path) ? path / kShardManifestName : path;
}

}  // namespace

std::string shard_map_name(int rank, uint64_t checkpoint_scans) { return numbered(rank, checkpoint_scans, ".bgk"); }
std::string shard_order_name(int rank, uint64_t checkpoint_scans) {
  return numbered(rank, checkpoint_scans, ".order");
}

void remove_checkpoints(const std::filesystem::path& folder, uint64_t keep_scans) {
  std::vector<std::filesystem::path> doomed;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    const std::string name = entry.path().filename().string();
    const size_t at = name.find(".at-");
    if (name.rfind("rank-", 0) != 0 || at == std::string::npos) continue;
    const size_t digits = name.find_first_not_of("0123456789", at + 4);
    if (digits == at + 4) continue;  // not a checkpoint's name
    if (keep_scans != 0 && std::stoull(name.substr(at + 4, std::min<size_t>(digits, name.size()) - at - 4)) >= keep_scans)
      continue;
    doomed.push_back(entry.path());
  }
  for (const auto& file : doomed) std::filesystem::remove(file);
}

void write_shard(const std::filesystem::path& folder, int rank, const BgkMap& map,
                 const std::vector<uint32_t>& created_by_scan, uint64_t checkpoint_scans) {
  if (created_by_scan.size() != map.block_count())
    throw std::logic_error("write_shard: one creating scan per block");
  write_native_map(folder / shard_map_name(rank, checkpoint_scans), map);
  write_file_atomically(folder / shard_order_name(rank, checkpoint_scans), [&](std::ostream& out) {
    out.write(kOrderMagic, sizeof kOrderMagic);
    const uint64_t n = created_by_scan.size();
    unsigned char count[8];
    for (int i = 0; i < 8; ++i) count[i] = static_cast<unsigned char>(n >> (8 * i));
    out.write(reinterpret_cast<const char*>(count), sizeof count);
    for (const uint32_t s : created_by_scan) {
      const unsigned char b[4] = {static_cast<unsigned char>(s), static_cast<unsigned char>(s >> 8),
                                  static_cast<unsigned char>(s >> 16), static_cast<unsigned char>(s >> 24)};
      out.write(reinterpret_cast<const char*>(b), sizeof b);
    }
  });
}

std::vector<uint32_t> read_shard_order(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot open shard order file");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (bytes.size() < 16 || std::memcmp(bytes.data(), kOrderMagic, sizeof kOrderMagic) != 0)
    throw InputError(file, "not a shard order file");
  uint64_t n = 0;
  for (int i = 0; i < 8; ++i) n |= uint64_t(static_cast<unsigned char>(bytes[8 + i])) << (8 * i);
  if (bytes.size() != 16 + 4 * n) throw InputError(file, "truncated shard order file");
  std::vector<uint32_t> order(n);
  for (uint64_t k = 0; k < n; ++k) {
    uint32_t v = 0;
    for (int i = 0; i < 4; ++i) v |= uint32_t(static_cast<unsigned char>(bytes[16 + 4 * k + i])) << (8 * i);
    order[k] = v;
  }
  return order;
}

void write_manifest(const std::filesystem::path& file, const ShardManifest& m) {
  nlohmann::json shards = nlohmann::json::array();
  for (size_t r = 0; r < m.shard_maps.size(); ++r) shards.push_back({{"map", m.shard_maps[r]}, {"order", m.shard_orders[r]}});
  const nlohmann::json held = held_inputs_to_json(m.held);
  const nlohmann::json j = {{"format", "bgkmap-shards"},
                            {"version", 1},
                            {"ranks", m.ranks},
                            {"scans", m.scans},
                            {"tile_blocks", 4},
                            {"partition_first_codes", m.partition},
                            {"shards", shards},
                            {"inputs", held}};
  write_file_atomically(file, [&](std::ostream& out) { out << j.dump(1) << '\n'; });
}

ShardManifest read_manifest(const std::filesystem::path& path) {
  const std::filesystem::path file = manifest_file(path);
  std::ifstream in(file);
  if (!in) throw InputError(file, "cannot open shard manifest");
  const nlohmann::json j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded() || !j.is_object() || !j.contains("format") || j["format"] != "bgkmap-shards")
    throw InputError(file, "not a bgkmap shard manifest");
  ShardManifest m;
  try {
    if (!j.contains("ranks") || !json_integer_fits<int>(j["ranks"]) || !j.contains("scans") ||
        !json_integer_fits<uint64_t>(j["scans"]))
      throw InputError(file, "corrupt shard manifest (\"ranks\" or \"scans\" is not a count)");
    m.ranks = j.at("ranks").get<int>();
    m.scans = j.at("scans").get<uint64_t>();
    m.partition = j.at("partition_first_codes").get<std::vector<uint64_t>>();
    for (const auto& s : j.at("shards")) {
      m.shard_maps.push_back(s.at("map").get<std::string>());
      m.shard_orders.push_back(s.at("order").get<std::string>());
    }
    m.held = held_inputs_from_json(file, j.at("inputs"), "corrupt shard manifest");
  } catch (const nlohmann::json::exception& e) {
    throw InputError(file, std::string("corrupt shard manifest (") + e.what() + ")");
  }
  if (m.ranks < 1 || m.shard_maps.size() != static_cast<size_t>(m.ranks))
    throw InputError(file, "corrupt shard manifest (the shards do not match the ranks)");
  try {
    if (SpatialPartition(m.partition).ranks() != m.ranks)
      throw std::invalid_argument("the partition does not match the ranks");
  } catch (const std::invalid_argument& e) {
    throw InputError(file, std::string("corrupt shard manifest (") + e.what() + ")");
  }
  return m;
}

void check_shard_blocks_owned(const BgkMap& shard, const SpatialPartition& partition, int rank,
                              const std::filesystem::path& file) {
  for (uint32_t slot = 0; slot < shard.block_count(); ++slot) {
    const int owner = partition.owner(shard.key_of_slot(slot));
    if (owner != rank)
      throw InputError(file, "holds a block of rank " + std::to_string(owner) + "'s part, not rank " +
                                 std::to_string(rank) + "'s (shards swapped, or of another run)");
  }
}

bool is_shard_manifest(const std::filesystem::path& path) {
  std::error_code ec;
  const std::filesystem::path file = manifest_file(path);
  if (!std::filesystem::is_regular_file(file, ec)) return false;
  std::ifstream in(file);
  char head[64] = {};
  in.read(head, sizeof head - 1);
  return std::strstr(head, "bgkmap-shards") != nullptr;
}

BgkMap merge_shards(const std::filesystem::path& path, ShardManifest* read, const ProgressCallback& progress) {
  const std::filesystem::path file = manifest_file(path);
  const ShardManifest m = read_manifest(file);
  const std::filesystem::path folder = file.parent_path();
  const SpatialPartition partition(m.partition);
  std::vector<BgkMap> shards;
  std::vector<std::vector<uint32_t>> orders;
  struct Entry {
    uint32_t scan;
    BlockKey key;
    uint32_t shard, slot;
  };
  std::vector<Entry> entries;
  ProgressCounter reading(progress, "read shards", "shards", static_cast<uint64_t>(m.ranks));
  for (int r = 0; r < m.ranks; ++r) {
    shards.push_back(read_native_map(folder / m.shard_maps[static_cast<size_t>(r)]));
    orders.push_back(read_shard_order(folder / m.shard_orders[static_cast<size_t>(r)]));
    const BgkMap& shard = shards.back();
    if (orders.back().size() != shard.block_count())
      throw InputError(folder / m.shard_orders[static_cast<size_t>(r)], "shard order file does not match its map's blocks");
    if (params_to_json(shard.params()) != params_to_json(shards.front().params()))
      throw InputError(folder / m.shard_maps[static_cast<size_t>(r)], "shard built with other parameters than shard 0");
    check_shard_blocks_owned(shard, partition, r, folder / m.shard_maps[static_cast<size_t>(r)]);
    for (uint32_t s = 0; s < shard.block_count(); ++s)
      entries.push_back({orders.back()[s], shard.key_of_slot(s), static_cast<uint32_t>(r), s});
    reading.add();
  }
  reading.finish();
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return block_file_order(a.scan, a.key, b.scan, b.key); });
  BgkMap merged(shards.front().params());
  const size_t cells = static_cast<size_t>(merged.cells_per_block());
  ProgressCounter copying(progress, "merge", "blocks", entries.size());
  for (const Entry& e : entries) {
    copying.add();
    if (merged.find_slot(e.key) >= 0)
      throw InputError(folder / m.shard_maps[e.shard], "a block is in two shards");
    const uint32_t slot = merged.ensure_slot(e.key);
    std::memcpy(merged.block_cells(slot), shards[e.shard].block_cells(e.slot), cells * sizeof(Cell));
  }
  copying.finish();
  if (read) *read = m;
  return merged;
}

NativeMapFile read_native_map_or_shards(const std::filesystem::path& path) {
  if (!is_shard_manifest(path)) return read_native_map_file(path);
  ShardManifest manifest;
  BgkMap map = merge_shards(path, &manifest);
  return {std::move(map), std::move(manifest.held), kNativeMapFormatVersion};
}

namespace {

BgkMap read_shard(const std::filesystem::path& folder, const ShardManifest& m, const SpatialPartition& partition,
                  int rank) {
  const std::filesystem::path file = folder / m.shard_maps.at(static_cast<size_t>(rank));
  BgkMap shard = read_native_map(file);
  check_shard_blocks_owned(shard, partition, rank, file);
  return shard;
}

}  // namespace

ShardedMapReader::ShardedMapReader(const std::filesystem::path& manifest)
    : folder_(manifest_file(manifest).parent_path()),
      manifest_(read_manifest(manifest)),
      partition_(manifest_.partition),
      shards_(static_cast<size_t>(manifest_.ranks)) {
  if (partition_.ranks() != manifest_.ranks)
    throw InputError(manifest_file(manifest), "corrupt shard manifest (the partition does not match the ranks)");
  shards_.front() = std::make_unique<BgkMap>(read_shard(folder_, manifest_, partition_, 0));  // the grid
}

const BgkMap& ShardedMapReader::map_at(double x, double y, double z) {
  const BgkMap& first = *shards_.front();
  // The block of the point's cell: a planar map's layer whatever z is.
  const int owner = partition_.owner(first.grid().block_of(first.cell_of(x, y, z)));
  std::unique_ptr<BgkMap>& shard = shards_[static_cast<size_t>(owner)];
  if (!shard) {
    shard = std::make_unique<BgkMap>(read_shard(folder_, manifest_, partition_, owner));
    if (params_to_json(shard->params()) != params_to_json(first.params()))
      throw InputError(folder_ / manifest_.shard_maps[static_cast<size_t>(owner)],
                       "shard built with other parameters than shard 0");
  }
  return *shard;
}

}  // namespace bgkmap
