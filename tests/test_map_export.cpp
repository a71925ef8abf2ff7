// bgkmap export: ROS map_server occupancy grids (.pgm + .yaml) read back as map_server reads them,
// and clouds of occupied cells (.ply, .pcd) read back with PCL, against the maps' own answers.
#include <gtest/gtest.h>
#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_export.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/native_map.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

namespace fs = std::filesystem;
using testing::CommandResult;
using testing::TempDir;

CommandResult run_cli(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

// ---- map_server's reading of a map (ROS 1 map_server image_loader.cpp, trinary mode) ----

struct MapServerMap {
  double resolution = 0;
  double origin[3] = {0, 0, 0};
  int width = 0, height = 0;
  std::vector<int8_t> data;  // OccupancyGrid order: row 0 the bottom (min y); 100, 0 or -1
  int8_t at(int column, int row) const { return data[static_cast<size_t>(row) * width + column]; }
};

// The YAML by yaml-cpp, the PGM (P5, maxval 255) byte by byte, then map_server's rule: with
// negate 0, p = (255 - value) / 255; occupied (100) if p > occupied_thresh, free (0) if
// p < free_thresh, else unknown (-1); image row j is grid row height - 1 - j.
MapServerMap load_as_map_server(const fs::path& yaml_file) {
  const YAML::Node doc = YAML::LoadFile(yaml_file.string());
  EXPECT_EQ(doc["mode"].as<std::string>(), "trinary");
  EXPECT_EQ(doc["negate"].as<int>(), 0);
  MapServerMap m;
  m.resolution = doc["resolution"].as<double>();
  for (int k = 0; k < 3; ++k) m.origin[k] = doc["origin"][k].as<double>();
  const double occupied_thresh = doc["occupied_thresh"].as<double>(), free_thresh = doc["free_thresh"].as<double>();
  const fs::path image = yaml_file.parent_path() / doc["image"].as<std::string>();
  std::istringstream in(testing::read_bytes(image));
  std::string magic;
  int maxval = 0;
  in >> magic >> m.width >> m.height >> maxval;
  in.get();  // the one whitespace byte before the pixels
  EXPECT_EQ(magic, "P5");
  EXPECT_EQ(maxval, 255);
  std::string pixels(static_cast<size_t>(m.width) * m.height, '\0');
  in.read(pixels.data(), static_cast<std::streamsize>(pixels.size()));
  EXPECT_EQ(in.gcount(), static_cast<std::streamsize>(pixels.size())) << image;
  EXPECT_EQ(in.peek(), std::char_traits<char>::eof()) << "bytes after the pixels of " << image;
  m.data.resize(pixels.size());
  for (int j = 0; j < m.height; ++j)
    for (int i = 0; i < m.width; ++i) {
      const double p = (255.0 - static_cast<unsigned char>(pixels[static_cast<size_t>(j) * m.width + i])) / 255.0;
      const int8_t value = p > occupied_thresh ? 100 : p < free_thresh ? 0 : -1;
      m.data[static_cast<size_t>(m.height - 1 - j) * m.width + i] = value;
    }
  return m;
}

int8_t map_server_value(CellState state) {
  return state == CellState::kOccupied ? 100 : state == CellState::kFree ? 0 : -1;
}

// ---- hand-made maps ----

void set_cell(BgkMap& map, const CellIndex& c, float alpha, float beta) {
  const uint32_t slot = map.ensure_slot(map.grid().block_of(c));
  Cell& cell = map.block_cells(slot)[map.grid().local_index(c)];
  cell.alpha = alpha, cell.beta = beta;
}

// A planar map of 0.5 m cells with one occupied cell at (-2, 3), one free at (1, -1), one with
// evidence but undecided at (0, 0): a 4 x 5 grid whose lower-left corner is (-1, -0.5) m.
BgkMap hand_made_planar_map() {
  BuildParams p;
  p.grid.resolution_m = 0.5;
  p.grid.block_depth = 2;
  p.set_planar(0.0);
  BgkMap map(p);
  const int32_t layer = p.planar_layer();
  set_cell(map, {-2, 3, layer}, 40.0f, 1.0f);
  set_cell(map, {1, -1, layer}, 1.0f, 40.0f);
  set_cell(map, {0, 0, layer}, 5.0f, 5.0f);
  return map;
}

TEST(RosMapExport, HandMadeMapHasItsCornerAtTheOriginAndPlusYUp) {
  TempDir dir("export");
  const BgkMap map = hand_made_planar_map();
  ASSERT_EQ(map.query(-0.75, 1.75, 0).state(map.params().classify), CellState::kOccupied);
  write_map(dir / "m.pgm", map);
  // The image exactly: its first row is y index 3 (the top edge), its last y index -1.
  std::string expected = "P5\n4 5\n255\n";
  std::string pixels(20, static_cast<char>(kRosUnknownPixel));
  pixels[0] = static_cast<char>(kRosOccupiedPixel);     // row 0, column 0: cell (-2, 3)
  pixels[4 * 4 + 3] = static_cast<char>(kRosFreePixel);  // row 4, column 3: cell (1, -1)
  EXPECT_EQ(testing::read_bytes(dir / "m.pgm"), expected + pixels);
  EXPECT_EQ(testing::read_bytes(dir / "m.yaml"),
            "image: \"m.pgm\"\nresolution: 0.5\norigin: [-1.0, -0.5, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
            "free_thresh: 0.1\nmode: trinary\n");
  const MapServerMap m = load_as_map_server(dir / "m.yaml");
  EXPECT_EQ(m.origin[0], -1.0);
  EXPECT_EQ(m.origin[1], -0.5);
  EXPECT_EQ(m.origin[2], 0.0);
  EXPECT_EQ(m.at(0, 4), 100);  // grid (0, 0) is the lower-left cell: x = -1..-0.5, y = -0.5..0
  EXPECT_EQ(m.at(3, 0), 0);
  EXPECT_EQ(m.at(2, 1), -1);  // the undecided cell (0, 0)
  int unknown = 0;
  for (const int8_t v : m.data) unknown += v == -1;
  EXPECT_EQ(unknown, 18);
}

// The three pixel values read back as exactly the three classes, with a margin both ways.
TEST(RosMapExport, ThresholdsReadBackTheThreeClasses) {
  const auto p = [](unsigned char v) { return (255.0 - v) / 255.0; };
  EXPECT_GT(p(kRosOccupiedPixel), kRosOccupiedThresh);
  EXPECT_LT(p(kRosFreePixel), kRosFreeThresh);
  EXPECT_GT(p(kRosUnknownPixel), kRosFreeThresh + 0.05);
  EXPECT_LT(p(kRosUnknownPixel), kRosOccupiedThresh - 0.05);
}

// The Intel Research Lab log built as docs/RESULTS.md (0.1 m, max range 20 m) with --2d: every
// pixel map_server reads equals BgkMap::query's class at the pixel's centre.
TEST(RosMapExport, IntelMapReadsBackAsTheMapsOwnClasses) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  TempDir dir("export-intel");
  const std::string log = (datasets / "carmen/intel-corrected.log.gz").string();
  const CommandResult built = run_cli("build -q " + log + " --2d --max-range 20 --resolution 0.1 --backend cpu -o " +
                                      (dir / "intel.bgk").string() + " -o " + (dir / "built.pgm").string());
  ASSERT_EQ(built.status, 0) << built.output;
  const CommandResult exported = run_cli("export " + (dir / "intel.bgk").string() + " -o " + (dir / "intel.pgm").string());
  ASSERT_EQ(exported.status, 0) << exported.output;
  EXPECT_EQ(testing::read_bytes(dir / "intel.pgm"), testing::read_bytes(dir / "built.pgm"));

  const BgkMap map = read_native_map(dir / "intel.bgk");
  const MapServerMap m = load_as_map_server(dir / "intel.yaml");
  EXPECT_EQ(m.resolution, 0.1);
  int32_t lo[2] = {INT32_MAX, INT32_MAX}, hi[2] = {INT32_MIN, INT32_MIN};
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior&) {
    lo[0] = std::min(lo[0], c.x), lo[1] = std::min(lo[1], c.y), hi[0] = std::max(hi[0], c.x), hi[1] = std::max(hi[1], c.y);
  });
  EXPECT_EQ(m.width, hi[0] - lo[0] + 1);
  EXPECT_EQ(m.height, hi[1] - lo[1] + 1);
  EXPECT_NEAR(m.origin[0], lo[0] * 0.1, 1e-12);
  EXPECT_NEAR(m.origin[1], lo[1] * 0.1, 1e-12);
  int mismatches = 0, counts[3] = {0, 0, 0};
  for (int row = 0; row < m.height; ++row)
    for (int column = 0; column < m.width; ++column) {
      const double x = m.origin[0] + (column + 0.5) * m.resolution, y = m.origin[1] + (row + 0.5) * m.resolution;
      const CellState state = map.query(x, y, 0.0).state(map.params().classify);
      ++counts[static_cast<int>(state)];
      if (m.at(column, row) != map_server_value(state) && mismatches++ < 5)
        ADD_FAILURE() << "pixel (" << column << ", " << row << ") at (" << x << ", " << y << ") is "
                      << int(m.at(column, row)) << ", the map says " << to_string(state);
    }
  EXPECT_EQ(mismatches, 0);
  EXPECT_GT(counts[static_cast<int>(CellState::kOccupied)], 2000);
  EXPECT_GT(counts[static_cast<int>(CellState::kFree)], 100000);
}

// ---- 3-D: the height band and the max-projection against a brute-force loop ----

BgkMap random_3d_map() {
  BuildParams params = testing::small_params(3);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& s : testing::random_scans(7, 3, 300, 1.5f)) mapper.insert(s);
  return mapper.map();
}

// Every column of the map's x-y box queried at every cell centre in the band, by the rule
// occupancy_grid.hpp states; the box from every cell with evidence in the band.
void expect_projection_is_brute_force(const BgkMap& map, const HeightBand& band, const std::string& what) {
  TempDir dir("export-3d");
  write_map_export(dir / "m.pgm", export_cells(map), band);
  const MapServerMap m = load_as_map_server(dir / "m.yaml");
  const double r = map.grid().resolution();
  int32_t lo[3] = {INT32_MAX, INT32_MAX, INT32_MAX}, hi[3] = {INT32_MIN, INT32_MIN, INT32_MIN};
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior&) {
    const int32_t v[3] = {c.x, c.y, c.z};
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], v[k]), hi[k] = std::max(hi[k], v[k]);
  });
  int32_t band_lo[2] = {INT32_MAX, INT32_MAX}, band_hi[2] = {INT32_MIN, INT32_MIN};
  for (int32_t z = lo[2]; z <= hi[2]; ++z) {
    if (!band.contains((z + 0.5) * r)) continue;
    map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior&) {
      if (c.z != z) return;
      band_lo[0] = std::min(band_lo[0], c.x), band_lo[1] = std::min(band_lo[1], c.y);
      band_hi[0] = std::max(band_hi[0], c.x), band_hi[1] = std::max(band_hi[1], c.y);
    });
  }
  ASSERT_EQ(m.width, band_hi[0] - band_lo[0] + 1) << what;
  ASSERT_EQ(m.height, band_hi[1] - band_lo[1] + 1) << what;
  EXPECT_NEAR(m.origin[0], band_lo[0] * r, 1e-12) << what;
  EXPECT_NEAR(m.origin[1], band_lo[1] * r, 1e-12) << what;
  int mismatches = 0, counts[3] = {0, 0, 0};
  for (int row = 0; row < m.height; ++row)
    for (int column = 0; column < m.width; ++column) {
      bool any_occupied = false, any_free = false;
      for (int32_t z = lo[2]; z <= hi[2]; ++z) {
        const double zc = (z + 0.5) * r;
        if (!band.contains(zc)) continue;
        const CellState s = map.query((band_lo[0] + column + 0.5) * r, (band_lo[1] + row + 0.5) * r, zc)
                                .state(map.params().classify);
        any_occupied |= s == CellState::kOccupied;
        any_free |= s == CellState::kFree;
      }
      const int8_t expected = any_occupied ? 100 : any_free ? 0 : -1;
      ++counts[expected == 100 ? 2 : expected == 0 ? 1 : 0];
      mismatches += m.at(column, row) != expected;
    }
  EXPECT_EQ(mismatches, 0) << what;
  EXPECT_GT(counts[2], 0) << what;
  EXPECT_GT(counts[1], 0) << what;
}

TEST(RosMapExport, ThreeDimensionalBandAndMaxProjectionAreTheBruteForce) {
  const BgkMap map = random_3d_map();
  expect_projection_is_brute_force(map, HeightBand{}, "every height");
  expect_projection_is_brute_force(map, height_band_between(-0.3, 0.25), "band [-0.3, 0.25]");
  expect_projection_is_brute_force(map, height_band_between(0.45, 0.45), "the one layer at 0.45");
  TempDir dir("export-3d");
  EXPECT_THROW(write_map_export(dir / "m.pgm", export_cells(map), height_band_between(40, 41)), bgkmap::InputError);
  EXPECT_FALSE(fs::exists(dir / "m.pgm"));
}

// ---- clouds of occupied cells, read back with PCL ----

// A cloud's points by field name (float32 fields of a PCLPointCloud2).
std::map<std::string, std::vector<float>> fields_of(const pcl::PCLPointCloud2& cloud) {
  std::map<std::string, std::vector<float>> out;
  const size_t n = static_cast<size_t>(cloud.width) * cloud.height;
  for (const pcl::PCLPointField& f : cloud.fields) {
    EXPECT_EQ(f.datatype, pcl::PCLPointField::FLOAT32) << f.name;
    std::vector<float>& values = out[f.name];
    for (size_t i = 0; i < n; ++i) {
      float v;
      std::memcpy(&v, cloud.data.data() + i * cloud.point_step + f.offset, sizeof v);
      values.push_back(v);
    }
  }
  return out;
}

// Float rounding of a double: within half a float ulp.
void expect_float_of(float actual, double expected, const std::string& what) {
  EXPECT_LE(std::abs(actual - expected), std::abs(expected) * 0x1p-24 + 1e-45) << what;
}

void expect_cloud_is_the_occupied_cells(const pcl::PCLPointCloud2& cloud, const BgkMap& map, const std::string& what) {
  std::map<std::string, std::vector<float>> f = fields_of(cloud);
  for (const char* name : {"x", "y", "z", "probability", "variance"}) ASSERT_EQ(f.count(name), 1u) << what << " " << name;
  std::map<std::tuple<int32_t, int32_t, int32_t>, CellPosterior> occupied;
  map.for_each_cell_with_evidence([&](const CellIndex& c, const CellPosterior& p) {
    if (p.state(map.params().classify) == CellState::kOccupied) occupied[{c.x, c.y, c.z}] = p;
  });
  ASSERT_GT(occupied.size(), 10u) << what;
  ASSERT_EQ(f["x"].size(), occupied.size()) << what;
  const Grid& grid = map.grid();
  std::set<std::tuple<int32_t, int32_t, int32_t>> seen;
  for (size_t i = 0; i < f["x"].size(); ++i) {
    const CellIndex c = grid.cell_of(f["x"][i], f["y"][i], f["z"][i]);
    const auto found = occupied.find({c.x, c.y, c.z});
    ASSERT_NE(found, occupied.end()) << what << ": point " << i << " is not an occupied cell";
    EXPECT_TRUE(seen.insert(found->first).second) << what << ": cell written twice";
    const Vec3d centre = grid.cell_center_d(c);
    expect_float_of(f["x"][i], centre.x, what + " x");
    expect_float_of(f["y"][i], centre.y, what + " y");
    expect_float_of(f["z"][i], centre.z, what + " z");
    expect_float_of(f["probability"][i], found->second.mean(), what + " probability");
    expect_float_of(f["variance"][i], found->second.variance(), what + " variance");
  }
}

TEST(CloudExport, PlyAndPcdHoldTheOccupiedCellsAsPclReadsThem) {
  TempDir dir("export-cloud");
  const BgkMap map = random_3d_map();
  write_map(dir / "m.ply", map);
  write_map(dir / "m.pcd", map);
  pcl::PCLPointCloud2 ply, pcd;
  ASSERT_EQ(pcl::io::loadPLYFile((dir / "m.ply").string(), ply), 0);
  ASSERT_EQ(pcl::io::loadPCDFile((dir / "m.pcd").string(), pcd), 0);
  expect_cloud_is_the_occupied_cells(ply, map, "ply");
  expect_cloud_is_the_occupied_cells(pcd, map, "pcd");
}

// gpom keeps no variance: its cloud has no variance field, and its probabilities are the ones
// the method answers for each cell.
TEST(CloudExport, AMethodWithoutVarianceLeavesTheFieldOut) {
  TempDir dir("export-gpom");
  BuildParams params = testing::small_planar_params();
  auto method = make_method("gpom", params, MethodParams{}, testing::cpu_backend());
  for (const Scan& s : testing::two_planar_scans()) method->insert(s);
  method->finish();
  method->write(dir / "m.pcd");
  method->write(dir / "m.pgm");
  pcl::PCLPointCloud2 cloud;
  ASSERT_EQ(pcl::io::loadPCDFile((dir / "m.pcd").string(), cloud), 0);
  std::map<std::string, std::vector<float>> f = fields_of(cloud);
  EXPECT_EQ(f.count("variance"), 0u);
  ASSERT_EQ(f.count("probability"), 1u);
  const Grid grid(params.grid);
  const double occupied_threshold = params.classify.occupied_threshold;
  ASSERT_GT(f["x"].size(), 0u);
  for (size_t i = 0; i < f["x"].size(); ++i) {
    const std::optional<CellEstimate> e = method->estimate(f["x"][i], f["y"][i], f["z"][i]);
    ASSERT_TRUE(e.has_value()) << i;
    EXPECT_GT(e->occupancy, occupied_threshold);
    expect_float_of(f["probability"][i], e->occupancy, "gpom probability");
    EXPECT_EQ(f["z"][i], f["z"][0]);
  }
  // Every known cell of the layer above the threshold is in the cloud.
  size_t occupied = 0;
  for (int32_t x = -10; x < 50; ++x)
    for (int32_t y = -10; y < 50; ++y) {
      const Vec3d c = grid.cell_center_d({x, y, grid.cell_of(0, 0, f["z"][0]).z});
      const std::optional<CellEstimate> e = method->estimate(c.x, c.y, c.z);
      occupied += e && e->occupancy > occupied_threshold;
    }
  EXPECT_EQ(occupied, f["x"].size());
  EXPECT_TRUE(fs::exists(dir / "m.yaml"));
}

// ---- the command's refusals: one line, non-zero, nothing written ----

TEST(ExportCommand, RefusesWhatItCannotWriteBeforeAnyWork) {
  TempDir dir("export-cli");
  write_map(dir / "m.bgk", hand_made_planar_map());
  const std::string map = (dir / "m.bgk").string();
  const auto expect_refused = [&](const std::string& args, const std::string& message) {
    const CommandResult r = run_cli(args);
    EXPECT_EQ(r.status, 1) << args << "\n" << r.output;
    EXPECT_NE(r.output.find(message), std::string::npos) << args << "\n" << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  };
  const CommandResult native = run_cli("export " + map + " -o " + (dir / "x.bgk").string());  // a usage error
  EXPECT_EQ(native.status, 2) << native.output;
  EXPECT_NE(native.output.find("x.bgk: export writes"), std::string::npos) << native.output;
  EXPECT_NE(native.output.find("give a name ending in .pgm, .ply or .pcd"), std::string::npos) << native.output;
  expect_refused("export " + map + " -o " + (dir / "x.pgm").string() + " --z-min 0 --z-max 1",
                 "x.pgm: a planar (--2d) map has one layer of cells: drop --z-min/--z-max");
  expect_refused("export " + map + " -o " + (dir / "x.pgm").string() + " --z-min 0", "--z-min and --z-max go together");
  expect_refused("export " + map + " -o " + (dir / "none" / "x.ply").string(), "cannot write into folder");
  expect_refused("export " + (dir / "missing.bgk").string() + " -o " + (dir / "x.ply").string(), "missing.bgk");
  expect_refused("build " + map + " -o " + (dir / "x.pgm").string() + " --report " + (dir / "x.yaml").string(),
                 "the map_server .yaml of -o " + (dir / "x.pgm").string() + " is written there");
  EXPECT_FALSE(fs::exists(dir / "x.pgm"));
  EXPECT_FALSE(fs::exists(dir / "x.yaml"));
  // An export is not a map bgkmap reads.
  const CommandResult ok = run_cli("export " + map + " -o " + (dir / "m.pgm").string() + " -o " + (dir / "m.ply").string());
  ASSERT_EQ(ok.status, 0) << ok.output;
  expect_refused("render " + (dir / "m.pgm").string() + " -o " + (dir / "r.png").string(),
                 "m.pgm: an export for other tools (.pgm, .ply, .pcd), which bgkmap does not read");
}

// --method octomap writes its own tree only; the probability methods refuse a .bgk alone.
TEST(ExportCommand, OctomapRefusesExportsAndGpomRefusesANativeMap) {
  const BuildParams params = testing::small_planar_params();
  const auto octomap = make_method("octomap", params, MethodParams{}, testing::cpu_backend());
  for (const char* name : {"o.pgm", "o.ply", "o.pcd", "o.bgk"})
    testing::expect_input_error(name, [&] { octomap->check_output(name); }, name);
  EXPECT_NO_THROW(octomap->check_output("o.bt"));
  const auto gpom = make_method("gpom", params, MethodParams{}, testing::cpu_backend());
  for (const char* name : {"g.pgm", "g.ply", "g.pcd", "g.ot"}) EXPECT_NO_THROW(gpom->check_output(name)) << name;
  testing::expect_input_error("g.bgk", [&] { gpom->check_output("g.bgk"); }, "gpom .bgk");
}

}  // namespace
}  // namespace bgkmap
