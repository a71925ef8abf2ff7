// The mapping methods of `bgkmap build --method`: each on a tiny hand-checked scene, and each
// against its plain reference (liboctomap called directly, ...).
#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <omp.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "integrate/brute_force.hpp"
#include "bgkmap/integrate/observations.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/methods/method.hpp"
#include "methods/bgk/bgk_method.hpp"
#include "methods/gp/gp_regression.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using testing::cpu_backend;

BuildParams params_at(double resolution, double max_range) {
  BuildParams params;
  params.grid.resolution_m = resolution;
  params.preprocess.max_range_m = max_range;
  return params;
}

// One beam along +x from the centre of cell (0,0,0) to the centre of cell (5,0,0).
Scan one_beam_scan() {
  Scan scan;
  scan.pose.position = {0.05f, 0.05f, 0.05f};
  scan.points = {{0.55f, 0.05f, 0.05f}};
  return scan;
}

// Leaves of a tree as (key, depth) -> log-odds.
using LeafValues = std::map<std::tuple<int, int, int, unsigned>, float>;
LeafValues leaf_values(const octomap::OcTree& tree) {
  LeafValues out;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const octomap::OcTreeKey k = it.getKey();
    out[{k[0], k[1], k[2], it.getDepth()}] = it->getLogOdds();
  }
  return out;
}

// A planar map (--2d) with every method: the scans' points are moved onto the layer's centre
// plane, every cell a method writes lies in that layer, and a query answers for the layer
// whatever its height.
TEST(EveryMethod, PlanarMapsKeepOneLayer) {
  BuildParams params = params_at(0.1, 1.5);
  params.set_planar(0.27);
  const int32_t layer = params.planar_layer();
  ASSERT_EQ(layer, 2);
  const std::vector<Scan> scans = testing::random_scans(31, 2, 120, 1.2f);  // 3-D points
  for (const std::string& name : method_names()) {
    SCOPED_TRACE(name);
    auto method = make_method(name, params, MethodParams{}, cpu_backend());
    for (const Scan& scan : scans) method->insert(scan);
    method->finish();
    ASSERT_GT(method->known_cells(), 50u);
    const std::filesystem::path dir = testing::make_temp_dir("methods_planar");
    method->write(dir / "map.ot");
    std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read((dir / "map.ot").string()));
    auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
    ASSERT_NE(tree, nullptr);
    size_t leaves = 0, answered = 0;
    for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it) {
      ASSERT_GE(it.getZ() - it.getSize() / 2, layer * 0.1 - 1e-6) << "a cell below the layer";
      ASSERT_LE(it.getZ() + it.getSize() / 2, (layer + 1) * 0.1 + 1e-6) << "a cell above the layer";
      ++leaves;
      const auto at_plane = method->occupancy(it.getX(), it.getY(), params.preprocess.plane_z_m);
      const auto elsewhere = method->occupancy(it.getX(), it.getY(), -3.0);
      ASSERT_EQ(at_plane.has_value(), elsewhere.has_value());
      if (at_plane) {
        EXPECT_EQ(*at_plane, *elsewhere);
        ++answered;
      }
    }
    EXPECT_GT(leaves, 0u);
    EXPECT_GT(answered, 0u);
    std::filesystem::remove_all(dir);
  }
}

// ---------------------------------------------------------------------------------------------
// octomap

// `bgkmap build` prepares each scan on a reader thread (prepare_scan) and maps it with
// insert_prepared: the time preparing took is still the scan's preprocessing and insert time, so
// that insert_s compares methods and back ends as before.
TEST(EveryMethod, CountsAPreparedScansPreparingTimeAsItsOwn) {
  BuildParams params = params_at(0.1, 1.2);
  params.preprocess.beyond_range = BeyondRange::kDrop;  // a path of its own in each method
  const Scan scan = testing::random_scans(5, 1, 200, 1.5f).front();
  for (const std::string& name : method_names()) {
    SCOPED_TRACE(name);
    auto method = make_method(name, params, MethodParams{}, cpu_backend());
    PreparedScan prepared = prepare_scan(scan, params.preprocess);
    const PreprocessCounts expected = prepared.counts;
    prepared.seconds = 1000;
    method->insert_prepared(std::move(prepared));
    method->finish();
    EXPECT_GE(method->timing().preprocess_s, 1000);
    EXPECT_LT(method->timing().preprocess_s, 1100);
    EXPECT_GE(method->timing().insert_s, 1000);
    ASSERT_EQ(method->per_scan_insert_s().size(), 1u);
    EXPECT_GE(method->per_scan_insert_s()[0], 1000);
    const PreprocessCounts& counts = method->counts().preprocess;
    EXPECT_EQ(counts.points_read, 200u);
    EXPECT_EQ(counts.points_read, expected.points_read);
    EXPECT_GT(counts.beyond_max_range, 0u);
    EXPECT_EQ(counts.hits + counts.beyond_max_range + expected.dropped_nonfinite, 200u);
  }
}

TEST(OctomapMethod, OneBeamFollowsOctomapsSensorModel) {
  const MethodParams method_params;  // OctoMap's defaults: hit 0.7, miss 0.4
  auto method = make_method("octomap", params_at(0.1, 0), method_params, cpu_backend());
  method->insert(one_beam_scan());
  method->finish();
  // The origin's cell and every cell up to the end cell: one miss each; the end cell one hit.
  for (int i = 0; i < 5; ++i) {
    const auto p = method->occupancy(0.05 + 0.1 * i, 0.05, 0.05);
    ASSERT_TRUE(p.has_value()) << "cell " << i;
    EXPECT_NEAR(*p, 0.4, 1e-6) << "cell " << i;
  }
  const auto hit = method->occupancy(0.55, 0.05, 0.05);
  ASSERT_TRUE(hit.has_value());
  EXPECT_NEAR(*hit, 0.7, 1e-6);
  EXPECT_FALSE(method->occupancy(0.65, 0.05, 0.05).has_value());
  EXPECT_FALSE(method->occupancy(0.25, 0.15, 0.05).has_value());
  EXPECT_EQ(method->known_cells(), 6u);
  EXPECT_EQ(method->counts().preprocess.hits, 1u);
  EXPECT_EQ(method->counts().preprocess.beams, 1u);
}

TEST(OctomapMethod, LeavesTheOpenMpThreadCountAsItWas) {
  // liboctomap's computeUpdate sets the calling thread's OpenMP team size to 1; a later method in
  // the same process (eval --methods, station-keeping) must still get every thread.
  omp_set_num_threads(3);
  auto method = make_method("octomap", params_at(0.1, 0), MethodParams{}, cpu_backend());
  method->insert(one_beam_scan());
  method->finish();
  EXPECT_EQ(omp_get_max_threads(), 3);
}

TEST(OctomapMethod, BeamBeyondMaxRangeClearsUpToItWithoutAHit) {
  MethodParams method_params;
  method_params.set("prob-miss", 0.3);
  auto method = make_method("octomap", params_at(0.1, 0.32), method_params, cpu_backend());
  method->insert(one_beam_scan());
  for (int i = 0; i < 3; ++i) {
    const auto p = method->occupancy(0.05 + 0.1 * i, 0.05, 0.05);
    ASSERT_TRUE(p.has_value()) << "cell " << i;
    EXPECT_NEAR(*p, 0.3, 1e-6) << "cell " << i;
  }
  EXPECT_FALSE(method->occupancy(0.35, 0.05, 0.05).has_value());
  EXPECT_FALSE(method->occupancy(0.55, 0.05, 0.05).has_value());
  EXPECT_EQ(method->counts().preprocess.beyond_max_range, 1u);
  EXPECT_EQ(method->counts().preprocess.hits, 0u);
}

TEST(OctomapMethod, BeamBeyondMaxRangeIsIgnoredWhenDropped) {
  BuildParams params = params_at(0.1, 0.32);
  params.preprocess.beyond_range = BeyondRange::kDrop;
  auto method = make_method("octomap", params, MethodParams{}, cpu_backend());
  Scan scan = one_beam_scan();
  scan.points.push_back({0.25f, 0.05f, 0.05f});  // within range: a hit at cell 2, misses before it
  method->insert(scan);
  for (int i = 0; i < 2; ++i) EXPECT_NEAR(*method->occupancy(0.05 + 0.1 * i, 0.05, 0.05), 0.4, 1e-6) << "cell " << i;
  EXPECT_NEAR(*method->occupancy(0.25, 0.05, 0.05), 0.7, 1e-6);
  EXPECT_FALSE(method->occupancy(0.35, 0.05, 0.05).has_value());  // the dropped beam cleared nothing past it
  EXPECT_EQ(method->counts().preprocess.beyond_max_range, 1u);
  EXPECT_EQ(method->counts().preprocess.hits, 1u);
  EXPECT_EQ(method->counts().preprocess.beams, 1u);
}

TEST(OctomapMethod, RepeatedHitsClampAtTheConfiguredBound) {
  MethodParams method_params;
  method_params.set("prob-hit", 0.9);
  method_params.set("clamp-max", 0.95);
  auto method = make_method("octomap", params_at(0.1, 0), method_params, cpu_backend());
  for (int i = 0; i < 3; ++i) method->insert(one_beam_scan());
  // logodds(0.9) * 3 = 6.59 > logodds(0.95) = 2.94: clamped.
  EXPECT_NEAR(*method->occupancy(0.55, 0.05, 0.05), 0.95, 1e-6);
}

TEST(OctomapMethod, EqualsLiboctomapCalledDirectly) {
  MethodParams method_params;
  method_params.set("prob-hit", 0.75);
  method_params.set("prob-miss", 0.35);
  method_params.set("clamp-min", 0.15);
  method_params.set("clamp-max", 0.95);
  const BuildParams params = params_at(0.2, 2.5);
  const std::vector<Scan> scans = testing::random_scans(7, 4, 300, 3.0f);

  auto method = make_method("octomap", params, method_params, cpu_backend());
  octomap::OcTree direct(0.2);
  direct.setProbHit(0.75);
  direct.setProbMiss(0.35);
  direct.setClampingThresMin(0.15);
  direct.setClampingThresMax(0.95);
  for (const Scan& scan : scans) {
    method->insert(scan);
    octomap::Pointcloud cloud;
    for (const Vec3f& p : scan.points) cloud.push_back(p.x, p.y, p.z);
    const Vec3f& o = scan.pose.position;
    direct.insertPointCloud(cloud, octomap::point3d(o.x, o.y, o.z), 2.5);
  }
  method->finish();

  const std::filesystem::path dir = testing::make_temp_dir("methods_octomap");
  method->write(dir / "map.ot");
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read((dir / "map.ot").string()));
  auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
  ASSERT_NE(tree, nullptr);
  const LeafValues expected = leaf_values(direct), got = leaf_values(*tree);
  ASSERT_GT(expected.size(), 1000u);
  EXPECT_EQ(got, expected);  // log-odds bit for bit, leaf for leaf
  for (auto it = direct.begin_leafs(), end = direct.end_leafs(); it != end; ++it) {
    const auto p = method->occupancy(it.getX(), it.getY(), it.getZ());
    ASSERT_TRUE(p.has_value());
    EXPECT_EQ(*p, it->getOccupancy());
  }
  std::filesystem::remove_all(dir);
}

TEST(OctomapMethod, RefusesNativeMapOutput) {
  auto method = make_method("octomap", params_at(0.1, 0), MethodParams{}, cpu_backend());
  EXPECT_THROW(method->check_output("map.bgk"), InputError);
  EXPECT_NO_THROW(method->check_output("map.bt"));
  EXPECT_NO_THROW(method->check_output("map.ot"));
}

TEST(OctomapMethod, RejectsAnInvalidSensorModel) {
  MethodParams bad;
  EXPECT_THROW(bad.set("prob-hit", 0.4), std::invalid_argument);
  bad.set("clamp-min", 0.98);  // each in range, but not below clamp-max (0.971)
  EXPECT_THROW(make_method("octomap", params_at(0.1, 0), bad, cpu_backend()), std::invalid_argument);
  EXPECT_THROW(make_method("nonsense", params_at(0.1, 0), MethodParams{}, cpu_backend()), std::invalid_argument);
}

// The shared reference: OctoMap of sim_structured at 0.1 m, max range 8, default sensor model.
TEST(OctomapMethod, ReproducesSimStructuredReferenceCellForCell) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const std::filesystem::path scene = datasets / "sim_structured";
  auto method = make_method("octomap", params_at(0.1, 8.0), MethodParams{}, cpu_backend());
  ScanSource source({scene});
  Scan scan;
  while (source.next(scan)) method->insert(scan);
  method->finish();
  EXPECT_EQ(method->counts().scans, 12u);

  const std::filesystem::path dir = testing::make_temp_dir("methods_octomap_reference");
  method->write(dir / "map.bt");
  octomap::OcTree got(0.1), expected(0.1);
  ASSERT_TRUE(got.readBinary((dir / "map.bt").string()));
  ASSERT_TRUE(expected.readBinary((scene / "octomap_reference.bt").string()));
  // Cell for cell at the finest depth: the reference file was pruned differently.
  got.expand();
  expected.expand();
  std::map<std::tuple<int, int, int, unsigned>, bool> got_leaves, expected_leaves;
  uint64_t known = 0;
  for (auto it = expected.begin_leafs(), end = expected.end_leafs(); it != end; ++it) {
    const octomap::OcTreeKey k = it.getKey();
    expected_leaves[{k[0], k[1], k[2], it.getDepth()}] = expected.isNodeOccupied(*it);
    ++known;
  }
  for (auto it = got.begin_leafs(), end = got.end_leafs(); it != end; ++it) {
    const octomap::OcTreeKey k = it.getKey();
    got_leaves[{k[0], k[1], k[2], it.getDepth()}] = got.isNodeOccupied(*it);
  }
  EXPECT_EQ(known, 197291u);  // the README's count of the reference's known cells
  EXPECT_EQ(method->known_cells(), known);
  EXPECT_EQ(got_leaves.size(), expected_leaves.size());
  EXPECT_TRUE(got_leaves == expected_leaves);
  std::filesystem::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------
// counting

// The method's map, through its native file (alpha and beta exactly as built).
BgkMap built_map(MappingMethod& method, const std::string& tag) {
  const std::filesystem::path dir = testing::make_temp_dir(tag);
  method.write(dir / "map.bgk");
  BgkMap map = read_native_map(dir / "map.bgk");
  std::filesystem::remove_all(dir);
  return map;
}

CellPosterior cell_posterior(const BgkMap& map, int x, int y, int z) {
  const double r = map.grid().resolution();
  return map.query((x + 0.5) * r, (y + 0.5) * r, (z + 0.5) * r);
}

TEST(CountingMethod, OneBeamCountsMissesAlongItAndAHitAtItsEnd) {
  BuildParams params = params_at(0.1, 0);
  params.preprocess.end_margin_m = 0.2;
  auto method = make_method("counting", params, MethodParams{}, cpu_backend());
  Scan scan;
  scan.pose.position = {0.02f, 0.05f, 0.05f};
  scan.points = {{0.57f, 0.05f, 0.05f}};  // free segment 0.02 -> 0.37: cells 0..3; hit in cell 5
  method->insert(scan);
  const BgkMap map = built_map(*method, "methods_counting_one_beam");
  EXPECT_EQ(map.params().kernel.type, KernelType::kBox);
  const float a0 = params.prior.alpha0, b0 = params.prior.beta0;
  for (int i = 0; i < 4; ++i) {
    const CellPosterior p = cell_posterior(map, i, 0, 0);
    EXPECT_FLOAT_EQ(p.alpha, a0) << "cell " << i;
    EXPECT_FLOAT_EQ(p.beta, b0 + 1.0f) << "cell " << i;
  }
  EXPECT_FALSE(cell_posterior(map, 4, 0, 0).has_evidence);
  EXPECT_FLOAT_EQ(cell_posterior(map, 5, 0, 0).alpha, a0 + 1.0f);
  EXPECT_FLOAT_EQ(cell_posterior(map, 5, 0, 0).beta, b0);
  EXPECT_FALSE(cell_posterior(map, 4, 1, 0).has_evidence);
  EXPECT_EQ(map.cells_with_evidence(), 5u);
}

TEST(CountingMethod, DiagonalBeamVisitsEachCrossedCellOnce) {
  BuildParams params = params_at(1.0, 0);
  params.preprocess.end_margin_m = 0;
  auto method = make_method("counting", params, MethodParams{}, cpu_backend());
  Scan scan;
  scan.pose.position = {0.5f, 0.2f, 0.5f};
  scan.points = {{2.5f, 1.2f, 0.5f}};  // y crosses 1 at x = 2.1: cells (0,0) (1,0) (2,0) (2,1)
  method->insert(scan);
  const BgkMap map = built_map(*method, "methods_counting_diagonal");
  const float b0 = params.prior.beta0;
  EXPECT_FLOAT_EQ(cell_posterior(map, 0, 0, 0).beta, b0 + 1.0f);
  EXPECT_FLOAT_EQ(cell_posterior(map, 1, 0, 0).beta, b0 + 1.0f);
  EXPECT_FLOAT_EQ(cell_posterior(map, 2, 0, 0).beta, b0 + 1.0f);
  EXPECT_FLOAT_EQ(cell_posterior(map, 2, 1, 0).beta, b0 + 1.0f);  // the end cell: no margin
  EXPECT_FLOAT_EQ(cell_posterior(map, 2, 1, 0).alpha, params.prior.alpha0 + 1.0f);
  EXPECT_FALSE(cell_posterior(map, 1, 1, 0).has_evidence);
  EXPECT_EQ(map.cells_with_evidence(), 4u);
}

// Counting is BGK-L with the box kernel: the same alpha and beta on every cell a beam crosses.
TEST(CountingMethod, EqualsBgklWithTheBoxKernel) {
  BuildParams params = params_at(0.1, 2.5);
  params.preprocess.end_margin_m = 0.2;
  const std::vector<Scan> scans = testing::random_scans(11, 3, 300, 2.0f);
  auto counting = make_method("counting", params, MethodParams{}, cpu_backend());
  BuildParams box = params;
  box.kernel.type = KernelType::kBox;
  auto bgkl = make_method("bgkl", box, MethodParams{}, cpu_backend());
  for (const Scan& scan : scans) {
    counting->insert(scan);
    bgkl->insert(scan);
  }
  const BgkMap got = built_map(*counting, "methods_counting_vs_box");
  const BgkMap expected = built_map(*bgkl, "methods_box");
  ASSERT_GT(got.cells_with_evidence(), 5000u);
  EXPECT_EQ(got.cells_with_evidence(), expected.cells_with_evidence());
  size_t compared = 0;
  for (uint32_t slot = 0; slot < got.block_count(); ++slot) {
    const BlockKey& key = got.key_of_slot(slot);
    for (int local = 0; local < got.cells_per_block(); ++local) {
      const CellPosterior p = got.posterior(got.block_cells(slot)[local]);
      if (!p.has_evidence) continue;
      const CellIndex c = got.grid().cell_at(key, local);
      const CellPosterior q = cell_posterior(expected, c.x, c.y, c.z);
      // Whole counts on a 0.001 prior, summed in another order: equal to float rounding.
      ASSERT_NEAR(p.alpha, q.alpha, 1e-4) << c.x << " " << c.y << " " << c.z;
      ASSERT_NEAR(p.beta, q.beta, 1e-4) << c.x << " " << c.y << " " << c.z;
      ++compared;
    }
  }
  EXPECT_EQ(compared, got.cells_with_evidence());
}

// ---------------------------------------------------------------------------------------------
// bgk (BGKOctoMap)

TEST(BgkMethod, SamplesFreePointsEverySpacingFromTheOrigin) {
  std::vector<Vec3f> points;
  sample_free_points({1.0f, 2.0f, 3.0f}, {1.0f, 2.0f, 3.35f}, 0.1, points);
  ASSERT_EQ(points.size(), 3u);
  for (int k = 0; k < 3; ++k) {
    EXPECT_FLOAT_EQ(points[k].x, 1.0f);
    EXPECT_FLOAT_EQ(points[k].y, 2.0f);
    EXPECT_NEAR(points[k].z, 3.0 + 0.1 * (k + 1), 1e-6);
  }
  points.clear();
  sample_free_points({0, 0, 0}, {0.05f, 0, 0}, 0.1, points);
  EXPECT_TRUE(points.empty());
}

// The sparse kernel, written out in double (T-RO 2019 eq. 13).
double sparse_kernel(double d, double ell, double sigma0) {
  if (d >= ell) return 0;
  const double pi = 3.14159265358979323846, x = d / ell;
  return sigma0 * ((2 + std::cos(2 * pi * x)) / 3 * (1 - x) + std::sin(2 * pi * x) / (2 * pi));
}

TEST(BgkMethod, OneBeamWeighsTheHitAndEachFreePoint) {
  BuildParams params = params_at(0.1, 0);
  params.preprocess.end_margin_m = 0.2;
  MethodParams method_params;
  method_params.set("free-resolution", 0.1);
  auto method = make_method("bgk", params, method_params, cpu_backend());
  Scan scan;
  scan.pose.position = {0.02f, 0.05f, 0.05f};
  scan.points = {{0.57f, 0.05f, 0.05f}};  // free segment to x = 0.37: free points at 0.12, 0.22, 0.32
  method->insert(scan);
  const BgkMap map = built_map(*method, "methods_bgk_one_beam");
  const double ell = params.kernel.ell_m, sigma0 = params.kernel.sigma0;
  for (int i = 0; i < 8; ++i) {
    const double cx = 0.05 + 0.1 * i;
    double beta = params.prior.beta0;
    for (const double free_x : {0.12, 0.22, 0.32}) beta += sparse_kernel(std::abs(cx - free_x), ell, sigma0);
    const double alpha = params.prior.alpha0 + sparse_kernel(std::abs(cx - 0.57), ell, sigma0);
    const CellPosterior p = cell_posterior(map, i, 0, 0);
    EXPECT_NEAR(p.alpha, alpha, 1e-5 * alpha) << "cell " << i;
    EXPECT_NEAR(p.beta, beta, 1e-5 * beta) << "cell " << i;
  }
}

// Against the plain reference: every free point as its own zero-length free segment.
TEST(BgkMethod, EqualsBruteForceOverHitsAndFreePoints) {
  BuildParams params = params_at(0.1, 1.5);
  MethodParams method_params;
  method_params.set("free-resolution", 0.15);
  const std::vector<Scan> scans = testing::random_scans(5, 2, 40, 1.2f);
  auto method = make_method("bgk", params, method_params, cpu_backend());
  std::vector<ScanObservations> reference;
  PreprocessCounts counts;
  for (const Scan& scan : scans) {
    method->insert(scan);
    ScanObservations beams;
    preprocess_scan(scan, params.preprocess, beams, counts);
    std::vector<Vec3f> free_points;
    for (const Vec3f& end : beams.free_ends) sample_free_points(beams.origin, end, 0.15, free_points);
    reference.push_back({beams.origin, beams.hits, {}});
    for (const Vec3f& p : free_points) reference.push_back({p, {}, {p}});
  }
  const BgkMap map = built_map(*method, "methods_bgk_brute_force");
  size_t with_evidence = 0;
  for (uint32_t slot = 0; slot < map.block_count(); ++slot) {
    const BlockKey key = map.key_of_slot(slot);
    for (int local = 0; local < map.cells_per_block(); ++local) {
      const Cell& cell = map.block_cells(slot)[local];
      const BruteForcePosterior ref = brute_force_cell(map.grid().cell_center_d(map.grid().cell_at(key, local)),
                                                       reference, params);
      ASSERT_NEAR(cell.alpha, ref.alpha, 1e-5 * ref.alpha);
      ASSERT_NEAR(cell.beta, ref.beta, 1e-5 * ref.beta);
      with_evidence += ref.beta > params.prior.beta0;
    }
  }
  EXPECT_GT(with_evidence, 1000u);
}

// ---------------------------------------------------------------------------------------------
// gpoctomap

// A 1-D toy: two training points on the x axis, the posterior by the closed-form 2x2 inverse.
TEST(GpRegression, EqualsTheClosedFormPosteriorOnA1DToy) {
  GpHyperParams hp;
  hp.ell_m = 0.3;
  hp.signal_var = 0.1;
  hp.noise_std = 0.1;
  const std::vector<Vec3d> train = {{0.0, 0, 0}, {0.1, 0, 0}};
  const std::vector<double> labels = {1.0, -1.0};
  const std::vector<Vec3d> test = {{0.05, 0, 0}, {0.2, 0, 0}, {-0.12, 0, 0}, {0.5, 0, 0}};
  const std::vector<GpPrediction> got = gp_predict(train, labels, test, hp);
  ASSERT_EQ(got.size(), test.size());

  const double k0 = sparse_kernel(0, hp.ell_m, hp.signal_var);
  const double a = k0 + hp.noise_std * hp.noise_std, b = sparse_kernel(0.1, hp.ell_m, hp.signal_var);
  const double det = a * a - b * b;
  for (size_t t = 0; t < test.size(); ++t) {
    const double k1 = sparse_kernel(std::abs(test[t].x - 0.0), hp.ell_m, hp.signal_var);
    const double k2 = sparse_kernel(std::abs(test[t].x - 0.1), hp.ell_m, hp.signal_var);
    // K^-1 = [[a, -b], [-b, a]] / det
    const double w1 = (a * labels[0] - b * labels[1]) / det, w2 = (-b * labels[0] + a * labels[1]) / det;
    const double mean = k1 * w1 + k2 * w2;
    const double quad = (k1 * (a * k1 - b * k2) + k2 * (-b * k1 + a * k2)) / det;
    EXPECT_NEAR(got[t].mean, mean, 1e-12) << "test point " << t;
    EXPECT_NEAR(got[t].variance, k0 - quad, 1e-12) << "test point " << t;
    EXPECT_EQ(got[t].observed, k1 != 0 || k2 != 0) << "test point " << t;
  }
  EXPECT_FALSE(got[3].observed);
  EXPECT_NEAR(got[3].variance, k0, 1e-15);  // beyond every training point's reach: the prior
}

TEST(BcmFusion, KIdenticalPredictionsFollowTheEquations) {
  const double prior_var = 0.1, squash = 0.1;
  const GpPrediction p{0.4, 0.05, true};
  BcmCell cell;
  for (int k = 1; k <= 5; ++k) {
    cell.add(p);
    // 1/var = K/var_k - (K-1)/prior_var; mean = var * K mu_k/var_k
    const double var = 1.0 / (k / p.variance - (k - 1) / prior_var);
    EXPECT_NEAR(cell.variance(prior_var), var, 1e-12) << k;
    EXPECT_NEAR(cell.mean(prior_var), var * k * p.mean / p.variance, 1e-12) << k;
    EXPECT_NEAR(cell.probability(squash), 1.0 / (1.0 + std::exp(-squash * k * p.mean / p.variance)), 1e-12) << k;
  }
  BcmCell one;
  one.add(p);
  EXPECT_NEAR(one.variance(prior_var), p.variance, 1e-15);  // one prediction is itself
  EXPECT_NEAR(one.mean(prior_var), p.mean, 1e-15);
}

// One hit and no free points (the beam is shorter than the end margin): the GP posterior of a
// single training point, k(d) / (k0 + sn^2) and k0 - k(d)^2 / (k0 + sn^2), squashed.
TEST(GpOctomapMethod, OneHitGivesTheSinglePointPosterior) {
  BuildParams params = params_at(0.1, 0);
  params.preprocess.end_margin_m = 0.2;
  MethodParams method_params;
  method_params.set("gp-noise", 0.1);
  method_params.set("gp-squash", 0.1);
  auto method = make_method("gpoctomap", params, method_params, cpu_backend());
  Scan scan;
  scan.pose.position = {0.02f, 0.05f, 0.05f};
  scan.points = {{0.17f, 0.05f, 0.05f}};
  method->insert(scan);
  const double ell = params.kernel.ell_m, sigma0 = params.kernel.sigma0;
  const double a = sparse_kernel(0, ell, sigma0) + 0.01;
  for (int i = 0; i < 4; ++i) {
    const double cx = 0.05 + 0.1 * i, k = sparse_kernel(std::abs(cx - double(0.17f)), ell, sigma0);
    const double mean = k / a, var = sparse_kernel(0, ell, sigma0) - k * k / a;
    const auto p = method->occupancy(cx, 0.05, 0.05);
    ASSERT_TRUE(p.has_value()) << "cell " << i;
    EXPECT_NEAR(*p, 1.0 / (1.0 + std::exp(-0.1 * mean / var)), 1e-6) << "cell " << i;
    EXPECT_GT(*p, 0.5);
  }
  EXPECT_FALSE(method->occupancy(0.45, 0.05, 0.05).has_value());  // 0.28 m away: beyond l
  // Known: exactly the cells whose centre lies within l of the hit (counted here by enumeration).
  uint64_t within = 0;
  for (int i = -5; i <= 5; ++i)
    for (int j = -5; j <= 5; ++j)
      for (int k = -5; k <= 5; ++k) {
        const double dx = 0.05 + 0.1 * i - double(0.17f), dy = 0.1 * j, dz = 0.1 * k;
        within += std::sqrt(dx * dx + dy * dy + dz * dz) < ell;
      }
  EXPECT_EQ(within, 28u);
  EXPECT_EQ(method->known_cells(), within);
  EXPECT_THROW(method->check_output("map.bgk"), InputError);
}

TEST(GpOctomapMethod, FreePointsPullCellsBelowOneHalf) {
  BuildParams params = params_at(0.1, 0);
  auto method = make_method("gpoctomap", params, MethodParams{}, cpu_backend());
  Scan scan;
  scan.pose.position = {0.02f, 0.05f, 0.05f};
  scan.points = {{1.57f, 0.05f, 0.05f}};
  method->insert(scan);
  EXPECT_LT(*method->occupancy(0.45, 0.05, 0.05), 0.5);
  EXPECT_GT(*method->occupancy(1.55, 0.05, 0.05), 0.5);
}

// The .ot of means holds each known cell's probability (log-odds as a float, not clamped to
// OctoMap's default bounds), the .bt the map's classification of it.
TEST(GpOctomapMethod, TreesHoldEveryKnownCellsProbabilityAndClass) {
  BuildParams params = params_at(0.1, 0);
  auto method = make_method("gpoctomap", params, MethodParams{}, cpu_backend());
  for (const Scan& scan : testing::random_scans(3, 2, 150, 1.2f)) method->insert(scan);
  method->finish();
  const std::filesystem::path dir = testing::make_temp_dir("methods_gpoctomap_tree");
  method->write(dir / "map.ot", TreeValues::kMean);
  method->write(dir / "map.bt");
  std::unique_ptr<octomap::AbstractOcTree> read(octomap::AbstractOcTree::read((dir / "map.ot").string()));
  auto* tree = dynamic_cast<octomap::OcTree*>(read.get());
  ASSERT_NE(tree, nullptr);
  octomap::OcTree binary(0.1);
  ASSERT_TRUE(binary.readBinary((dir / "map.bt").string()));
  const ClassifyParams& classify = params.classify;
  uint64_t leaves = 0, beyond_default_clamping = 0, occupied = 0, free = 0;
  for (auto it = tree->begin_leafs(), end = tree->end_leafs(); it != end; ++it) {
    const double size = it.getSize(), r = 0.1;
    for (double dx = r / 2; dx < size; dx += r)  // a pruned leaf stands for several equal cells
      for (double dy = r / 2; dy < size; dy += r)
        for (double dz = r / 2; dz < size; dz += r) {
          const double x = it.getX() - size / 2 + dx, y = it.getY() - size / 2 + dy, z = it.getZ() - size / 2 + dz;
          const auto p = method->occupancy(x, y, z);
          ASSERT_TRUE(p.has_value());
          EXPECT_NEAR(it->getOccupancy(), std::clamp(*p, 1e-6, 1 - 1e-6), 1e-6);
          beyond_default_clamping += *p > 0.971 || *p < 0.1192;
          ++leaves;
          const octomap::OcTreeNode* node = binary.search(x, y, z);
          if (*p > classify.occupied_threshold) {
            ASSERT_NE(node, nullptr);
            EXPECT_TRUE(binary.isNodeOccupied(node));
            ++occupied;
          } else if (*p < classify.free_threshold) {
            ASSERT_NE(node, nullptr);
            EXPECT_FALSE(binary.isNodeOccupied(node));
            ++free;
          } else {
            EXPECT_EQ(node, nullptr);
          }
        }
  }
  EXPECT_EQ(leaves, method->known_cells());
  EXPECT_GT(beyond_default_clamping, 0u);  // the values OctoMap's default clamping would have cut
  EXPECT_GT(occupied, 0u);
  EXPECT_GT(free, 0u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap
