// Map files: the native .bgk format against an independent reading of its documented layout
// (bit-exact round trips, resumed builds, every truncation and bit flip rejected), and the OctoMap
// exports read back through liboctomap.
#include <gtest/gtest.h>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>
#include <sys/resource.h>

#include <algorithm>
#include <cmath>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <vector>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/core/params_io.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/mapper.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Helpers

class TempDir {
 public:
  explicit TempDir(const std::string& tag) : path_(testing::make_temp_dir(tag)) {}
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }
  fs::path operator/(const std::string& name) const { return path_ / name; }
  std::set<std::string> entries() const {
    std::set<std::string> names;
    for (const auto& e : fs::directory_iterator(path_)) names.insert(e.path().filename().string());
    return names;
  }

 private:
  fs::path path_;
};


using testing::write_bytes;

BgkMap build_map(const BuildParams& params, const std::vector<Scan>& scans) {
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : scans) mapper.insert(s);
  return mapper.map();
}

// Every parameter away from its default, so that a field the format forgot cannot pass.
BuildParams unusual_params(int block_depth, KernelType kernel) {
  BuildParams p;
  p.grid.resolution_m = 0.0725;
  p.grid.block_depth = block_depth;
  p.kernel.type = kernel;
  p.kernel.ell_m = 0.17f;
  p.kernel.sigma0 = 0.83f;
  p.prior.alpha0 = 0.0021f;
  p.prior.beta0 = 0.0017f;
  p.preprocess.downsample_m = 0.013;
  p.preprocess.max_range_m = 2.2;
  p.preprocess.beyond_range = BeyondRange::kDrop;
  p.preprocess.end_margin_m = 0.05;
  p.preprocess.apply_viewpoint = true;
  p.classify.occupied_threshold = 0.66f;
  p.classify.free_threshold = 0.34f;
  p.classify.var_threshold = 0.05f;
  return p;
}

// A small map with blocks on both sides of every axis.
BuildParams small_params() {
  BuildParams p;
  p.grid.resolution_m = 0.1;
  p.grid.block_depth = 3;
  p.kernel.sigma0 = 1.0f;  // enough evidence for some cells to be classified at the default thresholds
  p.preprocess.end_margin_m = 0.1;
  p.preprocess.max_range_m = 2.5;
  return p;
}

void expect_same_params(const BuildParams& a, const BuildParams& b) {
  EXPECT_EQ(params_to_json(a), params_to_json(b));
  EXPECT_EQ(a.grid.resolution_m, b.grid.resolution_m);
  EXPECT_EQ(a.grid.block_depth, b.grid.block_depth);
  EXPECT_EQ(a.kernel.type, b.kernel.type);
  EXPECT_EQ(a.kernel.ell_m, b.kernel.ell_m);
  EXPECT_EQ(a.kernel.sigma0, b.kernel.sigma0);
  EXPECT_EQ(a.prior.alpha0, b.prior.alpha0);
  EXPECT_EQ(a.prior.beta0, b.prior.beta0);
  EXPECT_EQ(a.preprocess.downsample_m, b.preprocess.downsample_m);
  EXPECT_EQ(a.preprocess.max_range_m, b.preprocess.max_range_m);
  EXPECT_EQ(a.preprocess.beyond_range, b.preprocess.beyond_range);
  EXPECT_EQ(a.preprocess.end_margin_m, b.preprocess.end_margin_m);
  EXPECT_EQ(a.preprocess.apply_viewpoint, b.preprocess.apply_viewpoint);
  EXPECT_EQ(a.classify.occupied_threshold, b.classify.occupied_threshold);
  EXPECT_EQ(a.classify.free_threshold, b.classify.free_threshold);
  EXPECT_EQ(a.classify.var_threshold, b.classify.var_threshold);
}

// Same parameters, same blocks in the same slots, every alpha and beta bit for bit.
void expect_identical_maps(const BgkMap& expected, const BgkMap& actual) {
  expect_same_params(expected.params(), actual.params());
  testing::expect_same_cells(expected, actual);
}

bool has_negative_block(const BgkMap& map) {
  for (uint32_t s = 0; s < map.block_count(); ++s) {
    const BlockKey& k = map.key_of_slot(s);
    if (k.x < 0 && k.y < 0 && k.z < 0) return true;
  }
  return false;
}

// Calls read_native_map and returns the InputError's message, checking that it names the file.
std::string native_read_error(const fs::path& file) {
  try {
    read_native_map(file);
  } catch (const InputError& e) {
    EXPECT_EQ(e.file(), file);
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(file.string() + ": ", 0), 0u) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
    return what;
  }
  ADD_FAILURE() << file << " was read without an error";
  return "";
}

// The documented layout, written out independently of src/io/native_map.cpp.
uint32_t reference_crc32(const char* data, size_t n) {
  uint32_t crc = 0xFFFFFFFFu;
  for (size_t i = 0; i < n; ++i) {
    crc ^= static_cast<uint8_t>(data[i]);
    for (int k = 0; k < 8; ++k) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}
uint32_t reference_crc32(const std::string& s) { return reference_crc32(s.data(), s.size()); }

uint32_t le_u32(const std::string& b, size_t at) {
  uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<uint32_t>(static_cast<uint8_t>(b.at(at + i))) << (8 * i);
  return v;
}
uint64_t le_u64(const std::string& b, size_t at) { return le_u32(b, at) | (static_cast<uint64_t>(le_u32(b, at + 4)) << 32); }
void put_le(std::string& out, uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) out.push_back(static_cast<char>((v >> (8 * i)) & 0xFFu));
}

const std::string kMagic("\x89" "BGK\r\n\x1a\n", 8);
const std::string kEndMarker("BGK:END\n", 8);

// A .bgk file with correct checksums around whatever header and block bytes the test supplies.
std::string craft_native_file(const std::string& json, uint32_t cells_per_block, uint64_t block_count,
                              const std::string& blocks, uint32_t version = 1) {
  std::string f = kMagic;
  put_le(f, version, 4);
  put_le(f, json.size(), 4);
  f += json;
  put_le(f, cells_per_block, 4);
  put_le(f, block_count, 8);
  if (version >= 3) put_le(f, blocks.size(), 8);
  put_le(f, reference_crc32(f), 4);
  f += blocks;
  put_le(f, reference_crc32(blocks), 4);
  return f + kEndMarker;
}

std::string block_record(const BlockKey& key, const std::vector<Cell>& cells) {
  std::string r;
  put_le(r, static_cast<uint32_t>(key.x), 4);
  put_le(r, static_cast<uint32_t>(key.y), 4);
  put_le(r, static_cast<uint32_t>(key.z), 4);
  for (const Cell& c : cells) {
    uint32_t a, b;
    std::memcpy(&a, &c.alpha, 4);
    std::memcpy(&b, &c.beta, 4);
    put_le(r, a, 4);
    put_le(r, b, 4);
  }
  return r;
}

uint32_t bits(float v) {
  uint32_t b;
  std::memcpy(&b, &v, 4);
  return b;
}

// A version-3 block body as docs/FORMAT.md lays it out: for alpha, then beta, the mask of the
// non-zero bytes of the field's bitmap (one bit per cell, set where the value's bits differ from
// the prior's), those bytes, then the marked values.
std::string v3_body(const std::vector<Cell>& cells, const Cell& prior) {
  std::string body;
  for (const bool alpha : {true, false}) {
    const auto value = [&](const Cell& c) { return bits(alpha ? c.alpha : c.beta); };
    const uint32_t at_prior = value(prior);
    std::vector<uint8_t> bitmap((cells.size() + 7) / 8, 0);
    for (size_t i = 0; i < cells.size(); ++i)
      if (value(cells[i]) != at_prior) bitmap[i / 8] = static_cast<uint8_t>(bitmap[i / 8] | (1 << (i % 8)));
    std::string mask((bitmap.size() + 7) / 8, '\0');
    for (size_t j = 0; j < bitmap.size(); ++j)
      if (bitmap[j] != 0) mask[j / 8] = static_cast<char>(mask[j / 8] | (1 << (j % 8)));
    body += mask;
    for (const uint8_t byte : bitmap)
      if (byte != 0) body.push_back(static_cast<char>(byte));
    for (const Cell& c : cells)
      if (value(c) != at_prior) put_le(body, value(c), 4);
  }
  return body;
}

// The inverse, on a body that is well formed.
std::vector<Cell> cells_of_v3_body(const std::string& body, size_t cells_per_block, const Cell& prior) {
  std::vector<Cell> cells(cells_per_block, prior);
  size_t at = 0;
  const size_t bytes = (cells_per_block + 7) / 8, masks = (bytes + 7) / 8;
  for (const bool alpha : {true, false}) {
    const std::string mask = body.substr(at, masks);
    at += masks;
    std::vector<uint8_t> bitmap(bytes, 0);
    for (size_t j = 0; j < bytes; ++j)
      if ((static_cast<uint8_t>(mask.at(j / 8)) >> (j % 8)) & 1u) bitmap[j] = static_cast<uint8_t>(body.at(at++));
    for (size_t i = 0; i < cells_per_block; ++i) {
      if (((bitmap[i / 8] >> (i % 8)) & 1u) == 0) continue;
      const uint32_t v = le_u32(body, at);
      at += 4;
      std::memcpy(alpha ? &cells[i].alpha : &cells[i].beta, &v, 4);
    }
  }
  EXPECT_EQ(at, body.size());
  return cells;
}

// A version-3 record: key, body length, body.
std::string v3_record(const BlockKey& key, const std::string& body) {
  std::string r;
  put_le(r, static_cast<uint32_t>(key.x), 4);
  put_le(r, static_cast<uint32_t>(key.y), 4);
  put_le(r, static_cast<uint32_t>(key.z), 4);
  put_le(r, body.size(), 4);
  return r + body;
}

// A map's blocks as version-2 records: write_native_map's file of the versions before 3.
std::string version2_file(const BgkMap& map) {
  std::string records;
  const size_t c = static_cast<size_t>(map.cells_per_block());
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const Cell* cells = map.block_cells(slot);
    records += block_record(map.key_of_slot(slot), std::vector<Cell>(cells, cells + c));
  }
  const std::string json =
      nlohmann::json{{"params", params_to_json(map.params())}, {"inputs", nlohmann::json::array()}}.dump();
  return craft_native_file(json, static_cast<uint32_t>(c), map.block_count(), records, 2);
}

// ---------------------------------------------------------------------------------------------
// Native .bgk

TEST(NativeMap, ReferenceCrcIsZlibsCrc32) {
  EXPECT_EQ(reference_crc32(std::string("123456789")), 0xCBF43926u);  // the standard check value
}

TEST(NativeMap, RoundTripIsBitExactForEveryDepthAndKernel) {
  TempDir dir("map-io");
  const struct {
    int depth;
    KernelType kernel;
  } cases[] = {{2, KernelType::kBox}, {3, KernelType::kSparse}, {5, KernelType::kSparse}};
  for (const auto& c : cases) {
    SCOPED_TRACE("block depth " + std::to_string(c.depth));
    const BgkMap map = build_map(unusual_params(c.depth, c.kernel), testing::random_scans(11, 3, 200, 1.5f));
    ASSERT_GT(map.cells_with_evidence(), 100u);
    ASSERT_TRUE(has_negative_block(map));
    const fs::path file = dir / ("depth" + std::to_string(c.depth) + ".bgk");
    write_map(file, map);
    expect_identical_maps(map, read_native_map(file));
  }
}

TEST(NativeMap, FileLayoutMatchesTheDocumentedFormat) {
  TempDir dir("map-io");
  const BgkMap map = build_map(unusual_params(3, KernelType::kSparse), testing::random_scans(5, 2, 100, 1.5f));
  const fs::path file = dir / "layout.bgk";
  write_native_map(file, map);
  const std::string b = testing::read_bytes(file);

  ASSERT_GE(b.size(), 16u);
  EXPECT_EQ(b.substr(0, 8), kMagic);
  EXPECT_EQ(le_u32(b, 8), 3u);
  EXPECT_EQ(kNativeMapFormatVersion, 3u);
  const size_t h = le_u32(b, 12);
  const nlohmann::json header = nlohmann::json::parse(b.substr(16, h));
  EXPECT_EQ(header, (nlohmann::json{{"params", params_to_json(map.params())}, {"inputs", nlohmann::json::array()}}));
  const uint32_t c = le_u32(b, 16 + h);
  const uint64_t blocks = le_u64(b, 20 + h);
  const uint64_t d = le_u64(b, 28 + h);
  EXPECT_EQ(c, 64u);
  EXPECT_EQ(blocks, map.block_count());
  EXPECT_EQ(le_u32(b, 36 + h), reference_crc32(b.data(), 36 + h));
  ASSERT_EQ(b.size(), 52 + h + d);

  const Cell prior{map.params().prior.alpha0, map.params().prior.beta0};
  size_t at = 40 + h, cells_at_prior = 0, moved_cells = 0;
  for (uint32_t slot = 0; slot < blocks; ++slot) {
    const BlockKey& key = map.key_of_slot(slot);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at)), key.x);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at + 4)), key.y);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at + 8)), key.z);
    const size_t body = le_u32(b, at + 12);
    const std::string raw = b.substr(at + 16, body);
    const std::vector<Cell> cells = cells_of_v3_body(raw, c, prior);
    ASSERT_EQ(raw, v3_body(cells, prior));  // one encoding of each block
    const Cell* expected = map.block_cells(slot);
    for (uint32_t i = 0; i < c; ++i) {
      ASSERT_EQ(bits(cells[i].alpha), bits(expected[i].alpha)) << "block " << slot << " cell " << i;
      ASSERT_EQ(bits(cells[i].beta), bits(expected[i].beta)) << "block " << slot << " cell " << i;
      const bool at_prior = bits(cells[i].alpha) == bits(prior.alpha) && bits(cells[i].beta) == bits(prior.beta);
      cells_at_prior += at_prior, moved_cells += !at_prior;
    }
    at += 16 + body;
  }
  EXPECT_GT(cells_at_prior, 0u);  // both kinds of cell are in the file
  EXPECT_GT(moved_cells, 0u);
  ASSERT_EQ(at, 40 + h + d);
  EXPECT_EQ(le_u32(b, at), reference_crc32(b.data() + 40 + h, d));
  EXPECT_EQ(b.substr(at + 4), kEndMarker);
}

// Cells whose alpha or only their beta moved, in a file made by the documented layout: read as
// they are, and written back as the same bytes (each map has one encoding).
TEST(NativeMap, Version3FileOfTheDocumentedLayoutReadsAndIsWrittenTheSame) {
  TempDir dir("map-io");
  BuildParams p;
  p.grid.block_depth = 3;  // 64 cells: 8 bitmap bytes, one mask byte
  const Cell prior{p.prior.alpha0, p.prior.beta0};
  std::vector<Cell> cells(64, prior);
  cells[1].beta = 2.5f;
  cells[6] = Cell{0.75f, 1e-30f};
  cells[63].alpha = 3e8f;
  const std::string json = nlohmann::json{{"params", params_to_json(p)}, {"inputs", nlohmann::json::array()}}.dump();
  const std::string crafted =
      craft_native_file(json, 64, 2,
                        v3_record({-1, 2, -3}, v3_body(cells, prior)) +
                            v3_record({0, 0, 0}, v3_body(std::vector<Cell>(64, prior), prior)),
                        3);
  write_bytes(dir / "crafted.bgk", crafted);
  const BgkMap map = read_native_map(dir / "crafted.bgk");
  ASSERT_EQ(map.block_count(), 2u);
  EXPECT_EQ(map.key_of_slot(0), (BlockKey{-1, 2, -3}));
  EXPECT_EQ(std::memcmp(map.block_cells(0), cells.data(), sizeof(Cell) * 64), 0);
  for (int i = 0; i < 64; ++i) EXPECT_EQ(bits(map.block_cells(1)[i].beta), bits(prior.beta));
  write_native_map(dir / "written.bgk", map);
  EXPECT_TRUE(testing::read_bytes(dir / "written.bgk") == crafted);
}

const HeldInput kHeldPcd{"scans/scan_01.pcd", std::string(64, 'a'), 1};
const HeldInput kHeldGraph{"walk.graph", "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef", 7};

TEST(NativeMap, HeldInputsRoundTripInTheHeader) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(5, 2, 100, 1.5f));
  const std::vector<HeldInput> held{kHeldPcd, kHeldGraph};
  write_native_map(dir / "held.bgk", map, held);
  const NativeMapFile read = read_native_map_file(dir / "held.bgk");
  EXPECT_EQ(read.version, 3u);
  EXPECT_EQ(read.held, held);
  expect_identical_maps(map, read.map);

  const std::string b = testing::read_bytes(dir / "held.bgk");
  const nlohmann::json header = nlohmann::json::parse(b.substr(16, le_u32(b, 12)));
  EXPECT_EQ(header["inputs"], (nlohmann::json::array({{{"path", "scans/scan_01.pcd"}, {"sha256", std::string(64, 'a')}, {"scans", 1}},
                                                      {{"path", "walk.graph"}, {"sha256", kHeldGraph.sha256}, {"scans", 7}}})));
}

// A distributed build writes a .bgk from its pieces, each record made by its own writer and put in
// place, and the records' checksum combined from theirs: the pieces, made and put in place in a
// scattered order, are write_native_map's file.
TEST(NativeMap, PiecesPutInPlaceInAnyOrderAreTheWrittenFile) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(7, 3, 150, 1.5f));
  ASSERT_GT(map.block_count(), 10u);
  const std::vector<HeldInput> held{kHeldPcd, kHeldGraph};
  write_native_map(dir / "whole.bgk", map, held);
  const std::string whole = testing::read_bytes(dir / "whole.bgk");

  const uint32_t blocks = map.block_count();
  std::vector<std::string> pieces(blocks);
  for (uint32_t k = 0; k < blocks; ++k) {
    const uint32_t scattered = blocks - 1 - k;  // the last record first
    const size_t length = append_native_map_record(pieces[scattered], map, scattered);
    EXPECT_EQ(length, pieces[scattered].size());
  }
  std::vector<uint32_t> crcs;
  std::vector<uint64_t> lengths;
  std::string records;
  for (const std::string& piece : pieces) {
    crcs.push_back(native_map_crc(piece.data(), piece.size()));
    lengths.push_back(piece.size());
    records += piece;
  }
  EXPECT_NE(*std::min_element(lengths.begin(), lengths.end()), *std::max_element(lengths.begin(), lengths.end()));
  const std::string assembled = native_map_head(map.params(), map.cells_per_block(), blocks, records.size(), held) +
                                records + native_map_tail(native_map_records_crc(crcs, lengths));
  EXPECT_EQ(assembled.size(), whole.size());
  EXPECT_TRUE(assembled == whole);
  // The combined checksum is the one of the records laid end to end.
  EXPECT_EQ(native_map_records_crc(crcs, lengths), native_map_crc(records.data(), records.size()));
  EXPECT_EQ(native_map_records_crc({}, {}), native_map_crc(nullptr, 0));
}

// tests/data/native_v1.bgk was written by bgkmap at format version 1 (a6ebd7b) from
// native_v1_scan.pcd: `build native_v1_scan.pcd -o native_v1.bgk --backend cpu --resolution 0.1
// --block-depth 2 --ell 0.2 --max-range 1`; native_v2.bgk the same (and `--origin 0,0,0`) at
// version 2 (bc68964), the same block records. Their values below are what those files hold.
TEST(NativeMap, ReadsTheVersion1And2GoldenFilesAndRewritesThemAsVersion3) {
  const fs::path v1_file = fs::path(BGKMAP_TEST_DATA_DIR) / "native_v1.bgk";
  const fs::path v2_file = fs::path(BGKMAP_TEST_DATA_DIR) / "native_v2.bgk";
  const NativeMapFile v1 = read_native_map_file(v1_file);
  EXPECT_EQ(v1.version, 1u);
  EXPECT_TRUE(v1.held.empty());
  const BuildParams& p = v1.map.params();
  EXPECT_EQ(p.grid.resolution_m, 0.1);
  EXPECT_EQ(p.grid.block_depth, 2);
  EXPECT_EQ(p.kernel.ell_m, 0.2f);
  EXPECT_EQ(p.preprocess.max_range_m, 1.0);
  EXPECT_EQ(v1.map.block_count(), 43u);
  EXPECT_EQ(v1.map.cells_with_evidence(), 151u);
  const CellPosterior hit = v1.map.query(0.35, 0.05, 0.05);
  EXPECT_EQ(static_cast<float>(hit.alpha), 0.117666662f);
  EXPECT_EQ(static_cast<float>(hit.beta), 0.0282808859f);
  const CellPosterior free_cell = v1.map.query(0.15, 0.05, 0.05);
  EXPECT_EQ(static_cast<float>(free_cell.alpha), 0.00100000005f);
  EXPECT_EQ(static_cast<float>(free_cell.beta), 0.16289258f);

  const NativeMapFile v2 = read_native_map_file(v2_file);
  EXPECT_EQ(v2.version, 2u);
  ASSERT_EQ(v2.held.size(), 1u);
  EXPECT_EQ(v2.held[0].scans, 1u);
  expect_identical_maps(v1.map, v2.map);

  TempDir dir("map-io");
  write_native_map(dir / "v3.bgk", v2.map, v2.held);
  const NativeMapFile v3 = read_native_map_file(dir / "v3.bgk");
  EXPECT_EQ(v3.version, 3u);
  EXPECT_EQ(v3.held, v2.held);
  expect_identical_maps(v1.map, v3.map);
  EXPECT_LT(fs::file_size(dir / "v3.bgk"), fs::file_size(v2_file));
}

// Maps of every block depth and kernel, as versions 2 and 3: the same cells, bit for bit.
TEST(NativeMap, Version2And3FilesOfAMapReadTheSameBits) {
  TempDir dir("map-io");
  for (const int depth : {1, 2, 3, 4}) {
    SCOPED_TRACE("block depth " + std::to_string(depth));
    const BgkMap map = build_map(unusual_params(depth, KernelType::kSparse), testing::random_scans(13, 3, 200, 1.5f));
    write_bytes(dir / "v2.bgk", version2_file(map));
    write_native_map(dir / "v3.bgk", map);
    const NativeMapFile v2 = read_native_map_file(dir / "v2.bgk"), v3 = read_native_map_file(dir / "v3.bgk");
    EXPECT_EQ(v2.version, 2u);
    EXPECT_EQ(v3.version, 3u);
    expect_identical_maps(map, v2.map);
    expect_identical_maps(v2.map, v3.map);
  }
}

TEST(NativeMap, EmptyMapRoundTrips) {
  TempDir dir("map-io");
  const BgkMap map(unusual_params(4, KernelType::kSparse));
  write_map(dir / "empty.bgk", map);
  expect_identical_maps(map, read_native_map(dir / "empty.bgk"));
}

TEST(NativeMap, ResumedBuildEqualsOneBuild) {
  TempDir dir("map-io");
  const BuildParams params = small_params();
  const auto scans = testing::random_scans(21, 4, 250, 1.5f);
  const BgkMap at_once = build_map(params, scans);

  const BgkMap first_half = build_map(params, {scans[0], scans[1]});
  write_map(dir / "half.bgk", first_half);
  Mapper resumed(read_native_map(dir / "half.bgk"), std::make_unique<CpuIntegrator>(2));
  resumed.insert(scans[2]);
  resumed.insert(scans[3]);

  ASSERT_GT(resumed.map().block_count(), first_half.block_count());  // the second half added blocks
  expect_identical_maps(at_once, resumed.map());
}

class CorruptNativeMap : public ::testing::Test {
 protected:
  void SetUp() override {
    BuildParams p = small_params();
    p.grid.block_depth = 2;  // small records: every offset of the file can be tried
    good_ = dir_ / "good.bgk";
    write_map(good_, build_map(p, testing::random_scans(3, 1, 4, 0.4f)));
    bytes_ = testing::read_bytes(good_);
    ASSERT_GT(bytes_.size(), 1000u);  // several blocks
    ASSERT_LT(bytes_.size(), 8000u);  // every byte is tried, each time reading the whole file
  }
  TempDir dir_{"map-io"};
  fs::path good_;
  std::string bytes_;
};

TEST_F(CorruptNativeMap, EveryTruncationIsRejected) {
  const fs::path file = dir_ / "cut.bgk";
  write_bytes(file, "");
  EXPECT_NE(native_read_error(file).find("empty file"), std::string::npos);
  for (size_t size = 1; size < bytes_.size(); ++size) {
    write_bytes(file, bytes_.substr(0, size));
    const std::string what = native_read_error(file);
    ASSERT_NE(what.find("truncated"), std::string::npos) << "cut at " << size << ": " << what;
  }
}

TEST_F(CorruptNativeMap, TrailingBytesAreRejected) {
  const fs::path file = dir_ / "long.bgk";
  write_bytes(file, bytes_ + "x");
  EXPECT_NE(native_read_error(file).find("corrupt"), std::string::npos);
}

TEST_F(CorruptNativeMap, EverySingleBitFlipIsRejected) {
  // CRC-32 detects every single-bit error; the magic, version and lengths are checked before it.
  const fs::path file = dir_ / "flipped.bgk";
  for (size_t at = 0; at < bytes_.size(); ++at) {
    for (const unsigned char mask : {0x01, 0x80}) {
      std::string bad = bytes_;
      bad[at] = static_cast<char>(bad[at] ^ mask);
      write_bytes(file, bad);
      ASSERT_FALSE(native_read_error(file).empty()) << "byte " << at << " mask " << int(mask);
    }
  }
}

TEST_F(CorruptNativeMap, FlipsReportWhatIsWrong) {
  const fs::path file = dir_ / "flipped.bgk";
  const size_t h = le_u32(bytes_, 12);
  const auto error_after_flip = [&](size_t at) {
    std::string bad = bytes_;
    bad[at] = static_cast<char>(bad[at] ^ 0x04);
    write_bytes(file, bad);
    return native_read_error(file);
  };
  EXPECT_NE(error_after_flip(1).find("bad magic"), std::string::npos);
  EXPECT_NE(error_after_flip(8).find("unsupported .bgk format version 7"), std::string::npos);
  EXPECT_NE(error_after_flip(28 + h).find("header (checksum mismatch"), std::string::npos);  // the records' length
  EXPECT_NE(error_after_flip(16 + h / 2).find("header (checksum mismatch"), std::string::npos);
  EXPECT_NE(error_after_flip(32 + h + 20).find("block data checksum mismatch"), std::string::npos);
  EXPECT_NE(error_after_flip(bytes_.size() - 12).find("block data checksum mismatch"), std::string::npos);
  EXPECT_NE(error_after_flip(bytes_.size() - 3).find("end marker"), std::string::npos);
}

TEST(NativeMapErrors, ForeignEmptyMissingAndFutureFiles) {
  TempDir dir("map-io");
  const fs::path text = dir / "notes.bgk";
  write_bytes(text, "these are not the cells you are looking for\n");
  EXPECT_NE(native_read_error(text).find("not a native .bgk map (bad magic)"), std::string::npos);

  const fs::path tiny = dir / "tiny.bgk";
  write_bytes(tiny, "x");
  EXPECT_NE(native_read_error(tiny).find("bad magic"), std::string::npos);

  EXPECT_NE(native_read_error(dir / "missing.bgk").find("no such file"), std::string::npos);
  EXPECT_NE(native_read_error(dir.path()).find("not a regular file"), std::string::npos);

  // A well-formed file of a later version: refused by version, whatever follows.
  const std::string json = nlohmann::json{{"params", params_to_json(BuildParams{})}}.dump();
  const fs::path future = dir / "future.bgk";
  write_bytes(future, craft_native_file(json, 512, 0, "", /*version=*/5));
  EXPECT_NE(native_read_error(future).find("unsupported .bgk format version 5 (this build reads versions 1 to 4)"),
            std::string::npos);
  // Version 4 without its "forget" key: refused naming it.
  const std::string json_v2 =
      nlohmann::json{{"params", params_to_json(BuildParams{})}, {"inputs", nlohmann::json::array()}}.dump();
  write_bytes(future, craft_native_file(json_v2, 512, 0, "", /*version=*/4));
  EXPECT_NE(native_read_error(future).find("corrupt .bgk header (\"forget\": missing in a version-4 map)"),
            std::string::npos);
  const fs::path zero = dir / "zero.bgk";
  write_bytes(zero, craft_native_file(json, 512, 0, "", /*version=*/0));
  EXPECT_NE(native_read_error(zero).find("version 0"), std::string::npos);
  // The same file at version 1 is a valid empty map, so the version is the only fault above.
  const fs::path old = dir / "old.bgk";
  write_bytes(old, craft_native_file(json, 512, 0, ""));
  EXPECT_EQ(read_native_map(old).block_count(), 0u);
  // Version 2 with its held inputs.
  const std::string json2 = nlohmann::json{{"params", params_to_json(BuildParams{})}, {"inputs", nlohmann::json::array()}}.dump();
  const fs::path current = dir / "current.bgk";
  write_bytes(current, craft_native_file(json2, 512, 0, "", 2));
  EXPECT_EQ(read_native_map(current).block_count(), 0u);
  write_bytes(current, craft_native_file(json2, 512, 0, "", 3));
  EXPECT_EQ(read_native_map(current).block_count(), 0u);
  EXPECT_EQ(read_native_map_file(current).method, "bgkl");  // no "method": written by bgkl
  // The method another one records, read back; a "method" that is not a name is corruption.
  BgkMap map{BuildParams{}};
  write_native_map(dir / "counting.bgk", map, {}, "counting");
  EXPECT_EQ(read_native_map_file(dir / "counting.bgk").method, "counting");
  write_native_map(dir / "bgkl.bgk", map);
  EXPECT_EQ(testing::read_bytes(dir / "bgkl.bgk").find("\"method\""), std::string::npos);
  const std::string bad = nlohmann::json{{"params", params_to_json(BuildParams{})}, {"inputs", nlohmann::json::array()},
                                         {"method", 7}}.dump();
  write_bytes(dir / "bad_method.bgk", craft_native_file(bad, 512, 0, "", 2));
  EXPECT_NE(native_read_error(dir / "bad_method.bgk").find("\"method\" is not a name"), std::string::npos);
}

// Headers (valid checksums) whose parameters would overflow the keys or let each point reach
// thousands of blocks: fuzzed ones grew past 1.2 GB under --resume. Refused by the parameter
// checks of the command line.
TEST(NativeMap, HeaderParametersBeyondTheLimitsAreRefused) {
  TempDir dir("map-io");
  BuildParams fine_cells, long_kernel;
  fine_cells.grid.resolution_m = 0.0001;
  long_kernel.kernel.ell_m = 100;
  for (const auto& [params, expected] : {std::pair{fine_cells, "resolution must be in [0.001, 10000] m"},
                                         std::pair{long_kernel, "ell 100 m reaches 125 blocks"}}) {
    const std::string json = nlohmann::json{{"params", params_to_json(params)}, {"inputs", nlohmann::json::array()}}.dump();
    const fs::path file = dir / "limits.bgk";
    write_bytes(file, craft_native_file(json, 512, 0, "", 2));
    const std::string error = native_read_error(file);
    EXPECT_NE(error.find("bad parameters in .bgk header"), std::string::npos) << error;
    EXPECT_NE(error.find(expected), std::string::npos) << error;
  }
}

// nlohmann's get<int> of 1e300 is a cast out of range (undefined behaviour under UBSan).
TEST(NativeMap, HeaderIntegersThatAreFloatsOrOutOfRangeAreRefused) {
  TempDir dir("map-io");
  for (const nlohmann::json& depth : {nlohmann::json(1e300), nlohmann::json(4.5), nlohmann::json(int64_t{1} << 40)}) {
    nlohmann::json params = params_to_json(BuildParams{});
    params["block_depth"] = depth;
    const std::string json = nlohmann::json{{"params", params}, {"inputs", nlohmann::json::array()}}.dump();
    const fs::path file = dir / "depth.bgk";
    write_bytes(file, craft_native_file(json, 512, 0, "", 2));
    const std::string error = native_read_error(file);
    EXPECT_NE(error.find("'block_depth' must be an integer"), std::string::npos) << depth << ": " << error;
  }
}

TEST(NativeMapErrors, HugeCountsAreRefusedBeforeAllocating) {
  TempDir dir("map-io");
  const std::string json = nlohmann::json{{"params", params_to_json(BuildParams{})}}.dump();
  const fs::path file = dir / "huge.bgk";

  // 2^40 blocks of 4 KiB promised by a checksummed header: refused against the file size.
  write_bytes(file, craft_native_file(json, 512, 1ull << 40, ""));
  EXPECT_NE(native_read_error(file).find("truncated .bgk map (header promises 1099511627776 blocks"), std::string::npos);
  write_bytes(file, craft_native_file(json, 512, ~0ull, ""));
  EXPECT_NE(native_read_error(file).find("truncated"), std::string::npos);

  // Version 3: blocks beyond what the records' bytes can hold, records beyond the file.
  const std::string json3 = nlohmann::json{{"params", params_to_json(BuildParams{})}, {"inputs", nlohmann::json::array()}}.dump();
  write_bytes(file, craft_native_file(json3, 512, 1ull << 40, std::string(170, 'x'), 3));
  EXPECT_NE(native_read_error(file).find("corrupt .bgk header (1099511627776 blocks cannot fit in 170 bytes of records)"),
            std::string::npos);
  std::string short_records = craft_native_file(json3, 512, 1, std::string(170, 'x'), 3);
  short_records.erase(40 + json3.size() + 20, 150);
  write_bytes(file, short_records);
  EXPECT_NE(native_read_error(file).find("truncated .bgk map (header promises 170 bytes of block records; file has 20)"),
            std::string::npos);
  // 2^16 blocks of 32 bytes promise 256 MiB of cells: refused against --max-memory before allocating.
  set_memory_limit_bytes(resident_memory_bytes() + (64u << 20));
  write_bytes(file, craft_native_file(json3, 512, 1u << 16, std::string(32u << 16, 'x'), 3));
  try {
    read_native_map(file);
    ADD_FAILURE() << "read without an error";
  } catch (const MemoryLimitExceeded& e) {
    EXPECT_NE(std::string(e.what()).find("reading " + file.string() + " (65536 blocks)"), std::string::npos) << e.what();
  }
  set_memory_limit_bytes(0);

  // A JSON header length of 4 GiB.
  std::string b = craft_native_file(json, 512, 0, "");
  for (int i = 0; i < 4; ++i) b[12 + i] = '\xff';
  write_bytes(file, b);
  EXPECT_NE(native_read_error(file).find("exceeds 1 MiB"), std::string::npos);
}

TEST(NativeMapErrors, BadHeaderContentsWithValidChecksums) {
  TempDir dir("map-io");
  const fs::path file = dir / "bad.bgk";
  nlohmann::json params = params_to_json(BuildParams{});

  write_bytes(file, craft_native_file("{\"params\": ", 512, 0, ""));
  EXPECT_NE(native_read_error(file).find("not a JSON object"), std::string::npos);
  write_bytes(file, craft_native_file("{\"parameters\": {}}", 512, 0, ""));
  EXPECT_NE(native_read_error(file).find("no \"params\""), std::string::npos);

  params["resolution"] = -0.1;
  write_bytes(file, craft_native_file(nlohmann::json{{"params", params}}.dump(), 512, 0, ""));
  EXPECT_NE(native_read_error(file).find("bad parameters in .bgk header: resolution must be"), std::string::npos);
  params = params_to_json(BuildParams{});
  params["colour"] = "blue";
  write_bytes(file, craft_native_file(nlohmann::json{{"params", params}}.dump(), 512, 0, ""));
  EXPECT_NE(native_read_error(file).find("unknown parameter 'colour'"), std::string::npos);

  // Default depth 4 has 512 cells per block.
  write_bytes(file, craft_native_file(nlohmann::json{{"params", params_to_json(BuildParams{})}}.dump(), 64, 0, ""));
  EXPECT_NE(native_read_error(file).find("64 cells per block, but block depth 4 has 512"), std::string::npos);
}

TEST(NativeMapErrors, BadHeldInputsWithValidChecksums) {
  TempDir dir("map-io");
  const fs::path file = dir / "bad.bgk";
  const nlohmann::json params = params_to_json(BuildParams{});
  const auto error_with_inputs = [&](const nlohmann::json* inputs) {
    nlohmann::json header{{"params", params}};
    if (inputs) header["inputs"] = *inputs;
    write_bytes(file, craft_native_file(header.dump(), 512, 0, "", 2));
    return native_read_error(file);
  };
  EXPECT_NE(error_with_inputs(nullptr).find("corrupt .bgk header (no \"inputs\" list)"), std::string::npos);
  const nlohmann::json not_a_list = "scan.pcd";
  EXPECT_NE(error_with_inputs(&not_a_list).find("no \"inputs\" list"), std::string::npos);
  const nlohmann::json no_path = nlohmann::json::array({{{"sha256", kHeldPcd.sha256}, {"scans", 1}}});
  EXPECT_NE(error_with_inputs(&no_path).find("held input 0: expected"), std::string::npos);
  const nlohmann::json upper = nlohmann::json::array({{{"path", "a.pcd"}, {"sha256", std::string(64, 'A')}, {"scans", 1}}});
  EXPECT_NE(error_with_inputs(&upper).find("held input 0: sha256 is not 64 lowercase hex digits"), std::string::npos);
  const nlohmann::json none = nlohmann::json::array(
      {{{"path", "a.pcd"}, {"sha256", kHeldPcd.sha256}, {"scans", 1}}, {{"path", "b.pcd"}, {"sha256", kHeldPcd.sha256}, {"scans", 0}}});
  EXPECT_NE(error_with_inputs(&none).find("held input 1: holds 0 scans"), std::string::npos);
  const nlohmann::json negative = nlohmann::json::array({{{"path", "a.pcd"}, {"sha256", kHeldPcd.sha256}, {"scans", -1}}});
  EXPECT_NE(error_with_inputs(&negative).find("held input 0: expected"), std::string::npos);
}

TEST(HeldInputs, Sha256IsTheStandardDigest) {
  TempDir dir("map-io");
  write_bytes(dir / "abc", "abc");
  write_bytes(dir / "empty", "");
  EXPECT_EQ(sha256_of_file(dir / "abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_of_file(dir / "empty"), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_THROW(sha256_of_file(dir / "missing"), InputError);
}

// Inputs match stored records by content, each record at most once; scans added extend a file's
// record or append one.
TEST(HeldInputs, MatchByContentAndRecordNewScans) {
  TempDir dir("map-io");
  write_bytes(dir / "a.pcd", "scan a");
  write_bytes(dir / "b.pcd", "scan b");
  write_bytes(dir / "a_copy.pcd", "scan a");
  write_bytes(dir / "g.graph", "graph");
  const std::vector<fs::path> files{dir / "a.pcd", dir / "g.graph", dir / "a_copy.pcd", dir / "b.pcd"};
  HeldInputs held({{"elsewhere/a.pcd", sha256_of_file(dir / "a.pcd"), 1},
                   {"g.graph", sha256_of_file(dir / "g.graph"), 3},
                   {"gone.pcd", std::string(64, 'f'), 1}});
  EXPECT_EQ(held.match(files), (std::vector<uint64_t>{1, 3, 0, 0}));  // the copy of a is not held twice
  EXPECT_EQ(held.scans(), 5u);
  held.add(files, 1, 3);  // the graph's fourth node
  held.add(files, 2, 0);
  EXPECT_EQ(held.records(),
            (std::vector<HeldInput>{{"elsewhere/a.pcd", sha256_of_file(dir / "a.pcd"), 1},
                                    {files[1].string(), sha256_of_file(dir / "g.graph"), 4, 5},  // and its size
                                    {"gone.pcd", std::string(64, 'f'), 1},
                                    {files[2].string(), sha256_of_file(dir / "a.pcd"), 1, 6}}));
}

// A file that has grown since its record (a log still being recorded) holds the record's scans
// when its beginning is the recorded content; one that changed otherwise is refused.
TEST(HeldInputs, AGrownFileHoldsItsRecordedBeginning) {
  TempDir dir("map-io");
  write_bytes(dir / "run.log", "line 1\nline 2\n");
  const HeldInput recorded{(dir / "run.log").string(), sha256_of_file(dir / "run.log"), 2, 14};
  write_bytes(dir / "run.log", "line 1\nline 2\nline 3\n");
  HeldInputs grown({recorded});
  EXPECT_EQ(grown.match({dir / "run.log"}), (std::vector<uint64_t>{2}));
  grown.add({dir / "run.log"}, 0, 2);
  EXPECT_EQ(grown.records(),
            (std::vector<HeldInput>{{recorded.path, sha256_of_file(dir / "run.log"), 3, 21}}));
  write_bytes(dir / "run.log", "line 1\nline X\nline 3\n");
  HeldInputs changed({recorded});
  testing::expect_input_error(dir / "run.log", [&] { changed.match({dir / "run.log"}); }, "changed log");
}

TEST(NativeMapErrors, BadBlockContentsWithValidChecksums) {
  TempDir dir("map-io");
  const fs::path file = dir / "bad.bgk";
  BuildParams p;
  p.grid.block_depth = 1;  // one cell per block
  const std::string json = nlohmann::json{{"params", params_to_json(p)}}.dump();
  const std::vector<Cell> good{{1.5f, 0.25f}};

  write_bytes(file, craft_native_file(json, 1, 2, block_record({1, -2, 3}, good) + block_record({-4, 5, 6}, good)));
  const BgkMap map = read_native_map(file);
  ASSERT_EQ(map.block_count(), 2u);
  EXPECT_EQ(map.key_of_slot(1), (BlockKey{-4, 5, 6}));
  EXPECT_EQ(map.block_cells(0)[0].alpha, 1.5f);

  write_bytes(file, craft_native_file(json, 1, 2, block_record({1, -2, 3}, good) + block_record({1, -2, 3}, good)));
  EXPECT_NE(native_read_error(file).find("block 1 repeats key (1, -2, 3)"), std::string::npos);
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 0.0f, -1.0f}) {
    write_bytes(file, craft_native_file(json, 1, 1, block_record({0, 0, 0}, {{1.0f, bad}})));
    EXPECT_NE(native_read_error(file).find("block 0 cell 0 has a non-positive or non-finite alpha/beta"),
              std::string::npos);
  }
}

// Version-3 records that are well framed and checksummed but wrong inside, each refused naming
// the block.
TEST(NativeMapErrors, BadVersion3RecordsWithValidChecksums) {
  TempDir dir("map-io");
  const fs::path file = dir / "bad.bgk";
  BuildParams p;
  p.grid.block_depth = 1;  // one cell per block: a 1-byte bitmap with 7 spare bits
  const Cell prior{p.prior.alpha0, p.prior.beta0};
  const std::string json = nlohmann::json{{"params", params_to_json(p)}, {"inputs", nlohmann::json::array()}}.dump();
  const std::string good = v3_body({{1.5f, 0.25f}}, prior);
  ASSERT_EQ(good.size(), 12u);  // per field: mask 1, bitmap 1, value 4
  const auto error_of = [&](uint64_t blocks, const std::string& records) {
    write_bytes(file, craft_native_file(json, 1, blocks, records, 3));
    return native_read_error(file);
  };
  write_bytes(file, craft_native_file(json, 1, 2, v3_record({1, -2, 3}, good) + v3_record({-4, 5, 6}, good), 3));
  const BgkMap map = read_native_map(file);
  ASSERT_EQ(map.block_count(), 2u);
  EXPECT_EQ(map.key_of_slot(1), (BlockKey{-4, 5, 6}));
  EXPECT_EQ(map.block_cells(1)[0].beta, 0.25f);

  EXPECT_NE(error_of(2, v3_record({1, -2, 3}, good) + v3_record({1, -2, 3}, good)).find("block 1 repeats key (1, -2, 3)"),
            std::string::npos);
  for (const float bad : {std::numeric_limits<float>::quiet_NaN(), std::numeric_limits<float>::infinity(), 0.0f, -1.0f})
    EXPECT_NE(error_of(1, v3_record({0, 0, 0}, v3_body({{1.0f, bad}}, prior)))
                  .find("block 0 cell 0 has a non-positive or non-finite alpha/beta"),
              std::string::npos);
  std::string prior_alpha = "\x01\x01";
  put_le(prior_alpha, bits(prior.alpha), 4);
  const std::vector<std::pair<std::string, std::string>> bodies{
      {std::string("\x02\x00", 2), "block 0: its alpha mask marks bytes beyond the bitmap"},
      {std::string("\x01\x02\x00", 3), "block 0: its alpha bitmap marks cells beyond the block"},
      {std::string("\x01\x00\x00", 3), "block 0: its alpha mask marks a bitmap byte that is 0"},
      {std::string("\x00\x01", 2), "block 0: it ends inside its beta bitmap"},
      {std::string("\x01\x01\x31\x32", 4), "block 0: it ends inside its alpha values"},
      {good.substr(0, 6), "block 0: it ends inside its beta mask"},
      {prior_alpha + std::string(1, '\0'), "block 0: cell 0's alpha is marked but is the prior's"},
      {std::string("\x00\x00x", 3), "block 0: 1 bytes follow its cells"},
  };
  for (const auto& [body, expected] : bodies)
    EXPECT_NE(error_of(1, v3_record({0, 0, 0}, body)).find(expected), std::string::npos) << expected;
  // Framing: a length out of bounds, records past the count, a count past the records.
  EXPECT_NE(error_of(1, v3_record({0, 0, 0}, "") + "xx").find("block 0 claims 0 bytes of cells (2 to 2)"),
            std::string::npos);
  std::string long_length = v3_record({0, 0, 0}, good);
  long_length[12] = static_cast<char>(good.size() + 1);
  EXPECT_NE(error_of(1, long_length).find("block 0 claims 13 bytes of cells (2 to 12)"), std::string::npos);
  EXPECT_NE(error_of(1, v3_record({0, 0, 0}, good) + v3_record({1, 0, 0}, good)).find("28 bytes follow the last block's record"),
            std::string::npos);
  EXPECT_NE(error_of(2, v3_record({0, 0, 0}, good) + std::string(20, 'x')).find("block 1 claims"), std::string::npos);
  EXPECT_NE(error_of(2, v3_record({0, 0, 0}, good) + std::string(15, 'x')).find("block 1 of 2 starts past the end"),
            std::string::npos);
  // 8 cells a side: a key of 2^30 blocks has cells past 2^31.
  const BuildParams depth4;
  const std::string json4 = nlohmann::json{{"params", params_to_json(depth4)}, {"inputs", nlohmann::json::array()}}.dump();
  const Cell prior4{depth4.prior.alpha0, depth4.prior.beta0};
  write_bytes(file, craft_native_file(json4, 512, 1, v3_record({1 << 30, 0, 0}, v3_body(std::vector<Cell>(512, prior4), prior4)), 3));
  EXPECT_NE(native_read_error(file).find("block 0 has an out-of-range key (1073741824, 0, 0)"), std::string::npos);
}

TEST(NativeMapErrors, AnOctomapFileIsNotANativeMap) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const fs::path bt = datasets / "octomap_samples" / "geb079.bt";
  ASSERT_TRUE(fs::is_regular_file(bt)) << bt;
  EXPECT_NE(native_read_error(bt).find("an OctoMap file, not a native .bgk map"), std::string::npos);
}

TEST(MapFormat, ChosenByExtension) {
  EXPECT_EQ(map_format_from_path("a/b/map.bgk"), MapFormat::kNative);
  EXPECT_EQ(map_format_from_path("map.BGK"), MapFormat::kNative);
  EXPECT_EQ(map_format_from_path("map.ot"), MapFormat::kOctomapTree);
  EXPECT_EQ(map_format_from_path("map.bt"), MapFormat::kOctomapBinary);
  EXPECT_EQ(map_format_from_path("map.PGM"), MapFormat::kRosMap);
  EXPECT_EQ(map_format_from_path("cells.ply"), MapFormat::kPlyCloud);
  EXPECT_EQ(map_format_from_path("cells.pcd"), MapFormat::kPcdCloud);
  for (const char* bad : {"map.png", "map.yaml", "map", "map.bgk.gz"}) {
    try {
      map_format_from_path(bad);
      ADD_FAILURE() << bad << " accepted";
    } catch (const InputError& e) {
      EXPECT_EQ(e.file(), fs::path(bad));
      EXPECT_NE(std::string(e.what()).find("expected .bgk, .ot, .bt, or an export: .pgm, .ply, .pcd"), std::string::npos)
          << e.what();
    }
  }
}

// ---------------------------------------------------------------------------------------------
// OctoMap exports

std::unique_ptr<octomap::OcTree> read_octree(const fs::path& file) {
  std::unique_ptr<octomap::AbstractOcTree> tree(octomap::AbstractOcTree::read(file.string()));
  if (!tree) return nullptr;
  std::unique_ptr<octomap::OcTree> octree(dynamic_cast<octomap::OcTree*>(tree.get()));
  if (octree) tree.release();
  return octree;
}

// Finest-level cells the tree's leaves cover (a pruned leaf at depth d covers 8^(16-d)).
uint64_t covered_cells(const octomap::OcTree& tree) {
  uint64_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    n += 1ull << (3 * (tree.getTreeDepth() - it.getDepth()));
  return n;
}

template <typename Visit>
void for_each_cell(const BgkMap& map, Visit visit) {
  const Grid& grid = map.grid();
  for (uint32_t slot = 0; slot < map.block_count(); ++slot)
    for (int local = 0; local < grid.cells_per_block(); ++local) {
      const CellIndex c = grid.cell_at(map.key_of_slot(slot), local);
      visit(c, grid.cell_center_d(c), map.posterior(map.block_cells(slot)[local]));
    }
}

TEST(OctomapKeys, BgkmapCellsAreOctomapKeys) {
  for (const double r : {0.1, 0.05, 0.0725, 0.25}) {
    const octomap::OcTree tree(r);
    const Grid grid(GridParams{r, 3});
    for (const int32_t i : {-32768, -20000, -1000, -9, -2, -1, 0, 1, 7, 999, 32767}) {
      const unsigned expected_key = static_cast<unsigned>(i + 32768);
      for (const double f : {0.5, 0.01, 0.99}) {  // centre, and just inside either face
        const double x = (i + f) * r;
        EXPECT_EQ(tree.coordToKey(x), expected_key) << "r " << r << " cell " << i << " at " << f;
        EXPECT_EQ(grid.cell_of(x, x, x).x, i) << "r " << r << " cell " << i << " at " << f;
      }
      EXPECT_NEAR(tree.keyToCoord(static_cast<octomap::key_type>(expected_key)), (i + 0.5) * r, 1e-9 * std::max(1, std::abs(i)));
    }
  }
}

TEST(OctomapTree, OfMeansHoldsThePosteriorMeanOfEveryCellWithEvidence) {
  TempDir dir("map-io");
  BuildParams p = small_params();
  p.grid.resolution_m = 0.0123456789 * 8;  // needs more than OctoMap's default 6 printed digits
  const BgkMap map = build_map(p, testing::random_scans(7, 3, 300, 1.5f));
  ASSERT_TRUE(has_negative_block(map));
  const fs::path file = dir / "map.ot";
  write_map(file, map, "bgkl", TreeValues::kMean);
  EXPECT_EQ(testing::read_bytes(file).rfind("# Octomap OcTree file\n# bgkmap ot-values mean\n", 0), 0u);  // the text header octovis expects
  const std::unique_ptr<octomap::OcTree> tree = read_octree(file);
  ASSERT_TRUE(tree) << "liboctomap could not read " << file;
  EXPECT_EQ(tree->getResolution(), map.grid().resolution());

  size_t with_evidence = 0, without_checked = 0;
  double lowest = 1, highest = 0;
  for_each_cell(map, [&](const CellIndex&, const Vec3d& c, const CellPosterior& post) {
    const octomap::OcTreeNode* node = tree->search(c.x, c.y, c.z);
    if (!post.has_evidence) {
      ASSERT_EQ(node, nullptr) << c.x << " " << c.y << " " << c.z;
      ++without_checked;
      return;
    }
    ++with_evidence;
    ASSERT_NE(node, nullptr) << c.x << " " << c.y << " " << c.z;
    const double mean = std::clamp(post.mean(), 1e-6, 1 - 1e-6);
    ASSERT_NEAR(node->getOccupancy(), mean, 1e-5) << c.x << " " << c.y << " " << c.z;
    lowest = std::min(lowest, mean);
    highest = std::max(highest, mean);
  });
  EXPECT_EQ(with_evidence, map.cells_with_evidence());
  EXPECT_GT(with_evidence, 1000u);
  EXPECT_GT(without_checked, 10u);
  EXPECT_LT(lowest, 0.1);  // values well away from OctoMap's default clamping survived
  EXPECT_GT(highest, 0.9);
  // The tree holds nothing else: its leaves cover exactly the cells with evidence.
  EXPECT_EQ(covered_cells(*tree), with_evidence);
  // Inner nodes carry the maximum of their children, as OctoMap's own updates leave them.
  size_t inner = 0;
  for (auto it = tree->begin_tree(), end = tree->end_tree(); it != end; ++it) {
    if (it.isLeaf()) continue;
    ++inner;
    ASSERT_EQ(it->getLogOdds(), it->getMaxChildLogOdds()) << "inner node at depth " << it.getDepth();
  }
  EXPECT_GT(inner, 16u);
  // Far outside the map: nothing.
  EXPECT_EQ(tree->search(50.0, -50.0, 50.0), nullptr);
}

TEST(OctomapBinary, KeepsTheMapsClassification) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(8, 4, 300, 1.5f));
  const fs::path file = dir / "map.bt";
  write_map(file, map);
  EXPECT_EQ(testing::read_bytes(file).rfind("# Octomap OcTree binary file", 0), 0u);
  octomap::OcTree tree(0.5);
  ASSERT_TRUE(tree.readBinary(file.string()));
  EXPECT_EQ(tree.getResolution(), map.grid().resolution());

  size_t occupied = 0, free = 0, unknown_with_evidence = 0;
  const ClassifyParams& classify = map.params().classify;
  for_each_cell(map, [&](const CellIndex&, const Vec3d& c, const CellPosterior& post) {
    const CellState state = post.state(classify);
    const octomap::OcTreeNode* node = tree.search(c.x, c.y, c.z);
    if (state == CellState::kUnknown) {
      unknown_with_evidence += post.has_evidence;
      ASSERT_EQ(node, nullptr) << c.x << " " << c.y << " " << c.z;
      return;
    }
    ASSERT_NE(node, nullptr) << c.x << " " << c.y << " " << c.z;
    ASSERT_EQ(tree.isNodeOccupied(node), state == CellState::kOccupied) << c.x << " " << c.y << " " << c.z;
    ++(state == CellState::kOccupied ? occupied : free);
  });
  EXPECT_GT(occupied, 50u);
  EXPECT_GT(free, 50u);
  EXPECT_GT(unknown_with_evidence, 50u);  // some cells with evidence are still unknown: left out
  EXPECT_EQ(covered_cells(tree), occupied + free);
}

TEST(OctomapExport, EmptyMapGivesAnEmptyTree) {
  TempDir dir("map-io");
  const BgkMap map(small_params());
  write_map(dir / "empty.ot", map);
  write_map(dir / "empty.bt", map);
  const std::unique_ptr<octomap::OcTree> ot = read_octree(dir / "empty.ot");
  ASSERT_TRUE(ot);
  EXPECT_EQ(ot->size(), 0u);
  octomap::OcTree bt(0.5);
  ASSERT_TRUE(bt.readBinary((dir / "empty.bt").string()));
  EXPECT_EQ(bt.size(), 0u);
}

// ---------------------------------------------------------------------------------------------
// Atomic output

const char* const kAllExtensions[] = {".bgk", ".ot", ".bt"};

TEST(MapOutput, IntoAMissingFolderFailsAndLeavesNothing) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(4, 1, 50, 1.0f));
  for (const char* ext : kAllExtensions) {
    EXPECT_THROW(write_map(dir / "missing" / (std::string("map") + ext), map), std::runtime_error) << ext;
  }
  EXPECT_FALSE(fs::exists(dir / "missing"));
  EXPECT_TRUE(dir.entries().empty());
}

// Limits the size of any file this process writes, so that a write fails part way as on a full disk.
class FileSizeLimit {
 public:
  explicit FileSizeLimit(rlim_t bytes) {
    old_handler_ = std::signal(SIGXFSZ, SIG_IGN);  // the write then fails with EFBIG instead
    getrlimit(RLIMIT_FSIZE, &old_);
    rlimit limited = old_;
    limited.rlim_cur = bytes;
    ok_ = setrlimit(RLIMIT_FSIZE, &limited) == 0;
  }
  ~FileSizeLimit() {
    setrlimit(RLIMIT_FSIZE, &old_);
    std::signal(SIGXFSZ, old_handler_);
  }
  bool ok() const { return ok_; }

 private:
  rlimit old_{};
  void (*old_handler_)(int) = nullptr;
  bool ok_ = false;
};

TEST(MapOutput, AWriteFailingPartWayLeavesTheOldFileAndNoTemporary) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(4, 2, 200, 1.5f));
  constexpr rlim_t kLimit = 1024;
  for (const char* ext : kAllExtensions) {
    SCOPED_TRACE(ext);
    const fs::path reference = dir / (std::string("reference") + ext);
    write_map(reference, map);
    ASSERT_GT(fs::file_size(reference), 4 * kLimit);  // so that the limited write fails part way
    fs::remove(reference);

    const fs::path target = dir / (std::string("map") + ext);
    write_bytes(target, "previous contents");
    {
      FileSizeLimit limit(kLimit);
      ASSERT_TRUE(limit.ok());
      EXPECT_THROW(write_map(target, map), std::runtime_error);
    }
    EXPECT_EQ(testing::read_bytes(target), "previous contents");
    EXPECT_EQ(dir.entries(), std::set<std::string>{target.filename().string()});
    fs::remove(target);
  }
}

TEST(MapOutput, ATargetThatCannotBeReplacedIsLeftAlone) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(4, 1, 50, 1.0f));
  for (const char* ext : kAllExtensions) {
    SCOPED_TRACE(ext);
    const fs::path target = dir / (std::string("map") + ext);
    fs::create_directories(target / "inside");  // a non-empty folder: rename onto it fails
    EXPECT_THROW(write_map(target, map), std::runtime_error);
    EXPECT_TRUE(fs::is_directory(target / "inside"));
    EXPECT_EQ(dir.entries(), std::set<std::string>{target.filename().string()});
    fs::remove_all(target);
  }
}

TEST(MapOutput, CellsBeyondOctomapsRangeAreRefused) {
  TempDir dir("map-io");
  BuildParams p = small_params();
  p.grid.resolution_m = 0.01;
  Scan scan;
  scan.points.push_back({300.0f, 0.0f, 0.0f});  // cell 30000: inside OctoMap's range
  scan.pose.position = {299.5f, 0.0f, 0.0f};
  Mapper inside(p, std::make_unique<CpuIntegrator>(1));
  inside.insert(scan);
  write_map(dir / "inside.ot", inside.map());
  EXPECT_TRUE(fs::is_regular_file(dir / "inside.ot"));

  scan.points[0] = {400.0f, 0.0f, 0.0f};  // cell 40000: beyond it
  scan.pose.position = {399.5f, 0.0f, 0.0f};
  Mapper beyond(p, std::make_unique<CpuIntegrator>(1));
  beyond.insert(scan);
  const fs::path target = dir / "beyond.ot";
  write_bytes(target, "previous contents");
  try {
    write_map(target, beyond.map());
    ADD_FAILURE() << "a cell beyond OctoMap's range was written";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("outside OctoMap's range"), std::string::npos) << e.what();
  }
  EXPECT_THROW(write_map(dir / "beyond.bt", beyond.map()), std::runtime_error);
  EXPECT_EQ(testing::read_bytes(target), "previous contents");
  write_map(dir / "beyond.bgk", beyond.map());  // the native format has no such limit
  expect_identical_maps(beyond.map(), read_native_map(dir / "beyond.bgk"));
  EXPECT_EQ(dir.entries(), (std::set<std::string>{"beyond.bgk", "beyond.ot", "inside.ot"}));
}

}  // namespace
}  // namespace bgkmap
