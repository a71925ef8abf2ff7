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

#include "bgkmap/core/params_io.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
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
float le_f32(const std::string& b, size_t at) {
  const uint32_t bits = le_u32(b, at);
  float f;
  std::memcpy(&f, &bits, 4);
  return f;
}
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
  EXPECT_EQ(le_u32(b, 8), 2u);
  EXPECT_EQ(kNativeMapFormatVersion, 2u);
  const size_t h = le_u32(b, 12);
  const nlohmann::json header = nlohmann::json::parse(b.substr(16, h));
  EXPECT_EQ(header, (nlohmann::json{{"params", params_to_json(map.params())}, {"inputs", nlohmann::json::array()}}));
  const uint32_t c = le_u32(b, 16 + h);
  const uint64_t blocks = le_u64(b, 20 + h);
  EXPECT_EQ(c, 64u);
  EXPECT_EQ(blocks, map.block_count());
  EXPECT_EQ(le_u32(b, 28 + h), reference_crc32(b.data(), 28 + h));

  const size_t record = 12 + 8 * c;
  ASSERT_EQ(b.size(), 44 + h + blocks * record);
  size_t at = 32 + h;
  for (uint32_t slot = 0; slot < blocks; ++slot, at += record) {
    const BlockKey& key = map.key_of_slot(slot);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at)), key.x);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at + 4)), key.y);
    ASSERT_EQ(static_cast<int32_t>(le_u32(b, at + 8)), key.z);
    const Cell* cells = map.block_cells(slot);
    for (uint32_t i = 0; i < c; ++i) {
      ASSERT_EQ(le_f32(b, at + 12 + 8 * i), cells[i].alpha);
      ASSERT_EQ(le_f32(b, at + 16 + 8 * i), cells[i].beta);
    }
  }
  EXPECT_EQ(le_u32(b, at), reference_crc32(b.data() + 32 + h, blocks * record));
  EXPECT_EQ(b.substr(at + 4), kEndMarker);
}

const HeldInput kHeldPcd{"scans/scan_01.pcd", std::string(64, 'a'), 1};
const HeldInput kHeldGraph{"walk.graph", "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef", 7};

TEST(NativeMap, HeldInputsRoundTripInTheHeader) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(5, 2, 100, 1.5f));
  const std::vector<HeldInput> held{kHeldPcd, kHeldGraph};
  write_native_map(dir / "held.bgk", map, held);
  const NativeMapFile read = read_native_map_file(dir / "held.bgk");
  EXPECT_EQ(read.version, 2u);
  EXPECT_EQ(read.held, held);
  expect_identical_maps(map, read.map);

  const std::string b = testing::read_bytes(dir / "held.bgk");
  const nlohmann::json header = nlohmann::json::parse(b.substr(16, le_u32(b, 12)));
  EXPECT_EQ(header["inputs"], (nlohmann::json::array({{{"path", "scans/scan_01.pcd"}, {"sha256", std::string(64, 'a')}, {"scans", 1}},
                                                      {{"path", "walk.graph"}, {"sha256", kHeldGraph.sha256}, {"scans", 7}}})));
}

// A distributed build writes a .bgk from its pieces, each record placed by its own writer and the
// records' checksum combined from theirs: the pieces, put in place in a scattered order, are
// write_native_map's file.
TEST(NativeMap, PiecesPutInPlaceInAnyOrderAreTheWrittenFile) {
  TempDir dir("map-io");
  const BgkMap map = build_map(small_params(), testing::random_scans(7, 3, 150, 1.5f));
  ASSERT_GT(map.block_count(), 10u);
  const std::vector<HeldInput> held{kHeldPcd, kHeldGraph};
  write_native_map(dir / "whole.bgk", map, held);
  const std::string whole = testing::read_bytes(dir / "whole.bgk");

  const std::string head = native_map_head(map.params(), map.cells_per_block(), map.block_count(), held);
  const uint64_t record = native_map_record_bytes(map.cells_per_block());
  std::string assembled(head.size() + map.block_count() * record, '\0');
  assembled.replace(0, head.size(), head);
  std::vector<uint32_t> crcs(map.block_count());
  for (uint32_t k = 0; k < map.block_count(); ++k) {
    const uint32_t scattered = map.block_count() - 1 - k;  // the last record first
    std::string one;
    append_native_map_record(one, map, scattered);
    ASSERT_EQ(one.size(), record);
    crcs[scattered] = native_map_crc(one.data(), one.size());
    assembled.replace(head.size() + scattered * record, record, one);
  }
  assembled += native_map_tail(native_map_records_crc(crcs, record));
  EXPECT_EQ(assembled.size(), whole.size());
  EXPECT_TRUE(assembled == whole);
  // The combined checksum is the one of the records laid end to end.
  const std::string records = whole.substr(head.size(), map.block_count() * record);
  EXPECT_EQ(native_map_records_crc(crcs, record), native_map_crc(records.data(), records.size()));
  EXPECT_EQ(native_map_records_crc({}, record), native_map_crc(nullptr, 0));
}

// tests/data/native_v1.bgk was written by bgkmap at format version 1 (a6ebd7b) from
// native_v1_scan.pcd: `build native_v1_scan.pcd -o native_v1.bgk --backend cpu --resolution 0.1
// --block-depth 2 --ell 0.2 --max-range 1`. Its values below are what that file holds.
TEST(NativeMap, ReadsTheVersion1GoldenFileAndRewritesItAsVersion2) {
  const fs::path golden = fs::path(BGKMAP_TEST_DATA_DIR) / "native_v1.bgk";
  const NativeMapFile v1 = read_native_map_file(golden);
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

  TempDir dir("map-io");
  write_native_map(dir / "v2.bgk", v1.map);
  const NativeMapFile v2 = read_native_map_file(dir / "v2.bgk");
  EXPECT_EQ(v2.version, 2u);
  expect_identical_maps(v1.map, v2.map);
  // Only the header differs: the block records, their checksum and the end marker are the same bytes.
  const std::string b1 = testing::read_bytes(golden), b2 = testing::read_bytes(dir / "v2.bgk");
  EXPECT_EQ(b1.substr(32 + le_u32(b1, 12)), b2.substr(32 + le_u32(b2, 12)));
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
  EXPECT_NE(error_after_flip(8).find("unsupported .bgk format version 6"), std::string::npos);
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
  write_bytes(future, craft_native_file(json, 512, 0, "", /*version=*/3));
  EXPECT_NE(native_read_error(future).find("unsupported .bgk format version 3 (this build reads versions 1 to 2)"),
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
  for (const auto& [params, expected] : {std::pair{fine_cells, "--resolution 0.0001 m is below 0.001 m"},
                                         std::pair{long_kernel, "--ell 100 m reaches 125 blocks"}}) {
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
