// bgkmap station-keeping (T-RO 2019 §V-D) as a user runs it: the numbers it reports after N
// insertions of one scan, against what each method must give (BGK-L: N times the evidence of one
// insertion; OctoMap: liboctomap fed the scan N times; GPOctoMap: the BCM of N identical
// predictions), and its refusals of malformed input.
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"
#include "integrate/brute_force.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using Result = testing::CommandResult;

// The bgkmap command with these arguments.
Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

std::string cell_arg(const std::string& name, const Vec3f& p) {
  char buf[128];
  std::snprintf(buf, sizeof buf, " --cell %s:%.9g,%.9g,%.9g", name.c_str(), p.x, p.y, p.z);
  return buf;
}

// One random scan in a 2 m box, written as PCD and read back (the reference uses what the
// command reads); cells: the cells of two hits within range and a point halfway along a third beam.
class StationKeeping : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("station_keeping");
    use_scan(testing::random_scans(11, 1, 400, 2.0f)[0]);
  }

  void use_scan(const Scan& scan) {
    write_pcd(dir_ / "scan.pcd", scan);
    ScanSource source({dir_ / "scan.pcd"});
    ASSERT_TRUE(source.next(scan_));
    cell_args_.clear();
    const Vec3f& o = scan_.pose.position;
    std::vector<Vec3f> in_range;  // well within --max-range 2.5: a hit and a whole beam
    for (const Vec3f& p : scan_.points)
      if (std::hypot(p.x - o.x, p.y - o.y, p.z - o.z) < 2.0f) in_range.push_back(p);
    ASSERT_GE(in_range.size(), 3u);
    const Vec3f& far = in_range[2];
    cells_ = {{"hit_a", in_range[0]},
              {"hit_b", in_range[1]},
              {"beam", {0.5f * (o.x + far.x), 0.5f * (o.y + far.y), 0.5f * (o.z + far.z)}}};
    for (const auto& [name, p] : cells_) cell_args_ += cell_arg(name, p);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }

  // Runs the command; returns methods[i]["cells"] of the one method asked for.
  nlohmann::json station_keeping(const std::string& method, const std::string& repeats, const std::string& flags) {
    const std::string json = (dir_ / (method + ".json")).string();
    const Result r = run("station-keeping -q " + (dir_ / "scan.pcd").string() + cell_args_ + " --repeats " + repeats +
                         " --methods " + method + " --json " + json + " " + flags);
    EXPECT_EQ(r.status, 0) << r.output;
    std::ifstream in(json);
    const nlohmann::json j = nlohmann::json::parse(in);
    EXPECT_EQ(j["methods"].size(), 1u);
    EXPECT_EQ(j["methods"][0]["method"], method);
    variance_of_ = j["methods"][0]["variance_of"].get<std::string>();
    return j["methods"][0]["cells"];
  }

  std::filesystem::path dir_;
  Scan scan_;
  std::vector<std::pair<std::string, Vec3f>> cells_;
  std::string cell_args_;
  std::string variance_of_;
};

// n times an increment added to a float cell: within 1e-5 of n * increment, plus the rounding of
// the n float additions (half an ulp of the stored value each, and n times that of the first; an
// increment far below alpha0, e.g. a kernel tail, is lost to it entirely).
void expect_n_times(double got, double want, int n, double stored, const std::string& what) {
  EXPECT_NEAR(got, want, 1e-5 * std::abs(want) + n * FLT_EPSILON * std::abs(stored)) << what;
}

TEST_F(StationKeeping, BgklEvidenceScalesWithInsertionsSoTheMeanHolds) {
  const double prior = 0.001f;  // alpha0 = beta0 as the map stores them
  const std::vector<int> repeats = {1, 15, 30, 60};
  const nlohmann::json cells = station_keeping("bgkl", "1,15,30,60", "--backend cpu --max-range 2.5");
  EXPECT_EQ(variance_of_, "beta_posterior");
  BuildParams params;
  params.preprocess.max_range_m = 2.5;
  const Grid grid(params.grid);
  const std::vector<ScanObservations> once = testing::observations_of({scan_}, params);
  for (const auto& [name, point] : cells_) {
    const nlohmann::json& series = cells[name];
    ASSERT_EQ(series.size(), repeats.size()) << name;
    ASSERT_TRUE(series[0]["known"].get<bool>()) << name;
    const double a1 = series[0]["alpha"].get<double>() - prior, b1 = series[0]["beta"].get<double>() - prior;
    // One insertion is the plain sum over the scan's observations.
    const BruteForcePosterior ref = brute_force_cell(grid.cell_center_d(grid.cell_of(point.x, point.y, point.z)), once, params);
    EXPECT_NEAR(a1 + prior, ref.alpha, 1e-5 * ref.alpha) << name;
    EXPECT_NEAR(b1 + prior, ref.beta, 1e-5 * ref.beta) << name;
    EXPECT_GT(std::max(a1, b1), 0.01) << name << ": the cell should hold evidence well above the prior";
    double previous_variance = INFINITY;
    for (size_t k = 0; k < repeats.size(); ++k) {
      const nlohmann::json& e = series[k];
      const int n = repeats[k];
      EXPECT_EQ(e["insertions"].get<int>(), n);
      const double alpha = e["alpha"].get<double>(), beta = e["beta"].get<double>();
      expect_n_times(alpha - prior, n * a1, n, alpha, name + " alpha, N=" + std::to_string(n));
      expect_n_times(beta - prior, n * b1, n, beta, name + " beta, N=" + std::to_string(n));
      // What the command reports as mean and variance is the Beta posterior of those alpha, beta.
      const double mean = e["mean"].get<double>(), variance = e["variance"].get<double>();
      EXPECT_DOUBLE_EQ(mean, alpha / (alpha + beta)) << name;
      EXPECT_DOUBLE_EQ(variance, alpha * beta / ((alpha + beta) * (alpha + beta) * (alpha + beta + 1))) << name;
      // The mean holds (up to the prior's weight, 0.002 against the evidence)...
      EXPECT_NEAR(mean, a1 / (a1 + b1), 0.002 / (n * (a1 + b1)) + 1e-5 * mean) << name << " N=" << n;
      // ...and the variance shrinks.
      EXPECT_LT(variance, previous_variance) << name << " N=" << n;
      previous_variance = variance;
    }
  }
}

TEST_F(StationKeeping, OctomapEqualsLiboctomapGivenTheScanNTimes) {
  const std::vector<int> repeats = {1, 2, 4, 30};
  {
    std::ofstream cfg(dir_ / "octomap.yaml");
    cfg << "prob_hit: 0.6\nclamp_max: 0.8\nresolution: 0.2\n";
  }
  const nlohmann::json cells = station_keeping(
      "octomap", "1,2,4,30", "--max-range 2.5 --config " + (dir_ / "octomap.yaml").string() + " --clamp-max 0.9");
  EXPECT_EQ(variance_of_, "none");
  octomap::OcTree direct(0.2);
  direct.setProbHit(0.6);
  direct.setClampingThresMax(0.9);
  octomap::Pointcloud cloud;
  for (const Vec3f& p : scan_.points) cloud.push_back(p.x, p.y, p.z);
  const Vec3f& o = scan_.pose.position;
  int inserted = 0;
  for (size_t k = 0; k < repeats.size(); ++k) {
    for (; inserted < repeats[k]; ++inserted) direct.insertPointCloud(cloud, octomap::point3d(o.x, o.y, o.z), 2.5);
    for (const auto& [name, p] : cells_) {
      const nlohmann::json& e = cells[name][k];
      const octomap::OcTreeNode* node = direct.search(p.x, p.y, p.z);
      ASSERT_NE(node, nullptr) << name;
      ASSERT_TRUE(e["known"].get<bool>()) << name;
      EXPECT_EQ(e["mean"].get<double>(), node->getOccupancy()) << name << " N=" << repeats[k];
      EXPECT_TRUE(e["variance"].is_null()) << name << ": OctoMap has no variance";
    }
  }
  // The hit cells reach the clamp: a value that moves with N, unlike BGK-L's mean.
  EXPECT_NEAR(cells["hit_a"][3]["mean"].get<double>(), 0.9, 1e-6);
}

TEST_F(StationKeeping, GpoctomapFusesIdenticalPredictionsByTheBcm) {
  use_scan(testing::random_scans(12, 1, 25, 1.0f)[0]);  // small: a GP solve per block and insertion
  const std::vector<int> repeats = {1, 15, 60};
  const double prior_var = 0.1, squash = 0.1;  // --sigma0 default, --gp-squash default
  const nlohmann::json cells = station_keeping("gpoctomap", "1,15,60", "--max-range 2.5 --threads 2");
  EXPECT_EQ(variance_of_, "gp_bcm_latent");
  for (const auto& [name, p] : cells_) {
    const nlohmann::json& series = cells[name];
    ASSERT_TRUE(series[0]["known"].get<bool>()) << name;
    const double mu = series[0]["gp_mean"].get<double>(), var = series[0]["variance"].get<double>();
    EXPECT_GT(var, 0) << name;
    EXPECT_LT(var, prior_var) << name;
    for (size_t k = 0; k < repeats.size(); ++k) {
      const double n = repeats[k];
      // Eqs. 20-21 with K identical predictions (mu, var). The GP's solve is not bitwise the same
      // each time (points reach a block in any order), and n / var - (n - 1) / prior_var cancels:
      // 1e-6 relative.
      const double fused_var = 1.0 / (n / var - (n - 1) / prior_var);
      const double fused_mean = fused_var * n * mu / var;
      EXPECT_NEAR(series[k]["variance"].get<double>(), fused_var, 1e-6 * fused_var) << name << " N=" << n;
      EXPECT_NEAR(series[k]["gp_mean"].get<double>(), fused_mean, 1e-6 * std::abs(fused_mean) + 1e-12) << name;
      EXPECT_NEAR(series[k]["mean"].get<double>(), 1 / (1 + std::exp(-squash * n * mu / var)), 1e-9) << name;
    }
    // The occupancy drifts away from 0.5 with every repeat.
    const double d1 = std::abs(series[0]["mean"].get<double>() - 0.5), d60 = std::abs(series[2]["mean"].get<double>() - 0.5);
    EXPECT_GT(d60, d1) << name;
  }
}

// The same scan again and again is more data each time: the logit's variance shrinks at every
// cell, and the probability stays strictly inside (0, 1).
TEST_F(StationKeeping, BhmLogitVarianceShrinksWithEveryRepeat) {
  use_scan(testing::random_scans(13, 1, 40, 1.0f)[0]);
  const nlohmann::json cells = station_keeping("bhm", "1,3,10", "--max-range 2.5 --threads 2");
  EXPECT_EQ(variance_of_, "bhm_logit");
  for (const auto& [name, p] : cells_) {
    const nlohmann::json& series = cells[name];
    for (size_t k = 0; k < series.size(); ++k) {
      ASSERT_TRUE(series[k]["known"].get<bool>()) << name;
      EXPECT_GT(series[k]["mean"].get<double>(), 0.0) << name;
      EXPECT_LT(series[k]["mean"].get<double>(), 1.0) << name;
      EXPECT_TRUE(series[k]["logit_mean"].is_number()) << name;
      if (k == 0) continue;
      EXPECT_LT(series[k]["variance"].get<double>(), series[k - 1]["variance"].get<double>()) << name;
    }
  }
}

TEST_F(StationKeeping, WritesThePlotAndIsListedInTheHelp) {
  const std::string png = (dir_ / "sk.png").string();
  const Result r = run("station-keeping -q " + (dir_ / "scan.pcd").string() + cell_args_ +
                       " --repeats 1,3 --methods bgkl,counting,octomap --backend cpu --max-range 2.5 --json " +
                       (dir_ / "sk.json").string() + " --plot " + png);
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(png, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  const Result help = run("--help");
  EXPECT_NE(help.output.find("station-keeping"), std::string::npos) << help.output;
}

TEST_F(StationKeeping, RefusesMalformedCellsAndRepeatsWithOneLine) {
  const std::string base = "station-keeping -q " + (dir_ / "scan.pcd").string() + " --json " + (dir_ / "x.json").string();
  for (const std::string bad : {"wall:1,2", "wall1,2,3", ":1,2,3", "wall:1,2,x", "wall:1,2,3,4", "wa/ll:1,2,3"}) {
    const Result r = run(base + " --cell " + bad);
    EXPECT_EQ(r.status, 1) << bad;
    EXPECT_NE(r.output.find("--cell '" + bad + "'"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("NAME:X,Y,Z"), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  for (const std::string far : {"wall:1e30,0,0", "wall:0,-3e9,0"}) {  // wrapped the 32-bit keys (UB)
    const Result r = run(base + " --cell " + far);
    EXPECT_EQ(r.status, 1) << far;
    EXPECT_NE(r.output.find("--cell '" + far + "': beyond the map's key range"), std::string::npos) << r.output;
  }
  Result r = run(base + " --cell a:0,0,0 --cell a:1,1,1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("'a' is given twice"), std::string::npos) << r.output;
  r = run(base + " --cell a:0,0,0 --repeats 15,1");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("--repeats"), std::string::npos) << r.output;
  {
    std::ofstream cfg(dir_ / "m.yaml");
    cfg << "method: bgkl\n";
  }
  r = run(base + " --cell a:0,0,0 --config " + (dir_ / "m.yaml").string());  // --methods chooses here
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("m.yaml: 'method' is not used by this command"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(dir_ / "x.json"));
}

// The scan is read as build reads it: an .xyz scan takes --origin, and --pose-covariance gives it
// the covariance --pose-sigma would (were both ignored, the first run would be refused and the
// last two would equal the plain run).
TEST_F(StationKeeping, ReadsTheScanWithTheOriginAndPoseCovarianceGiven) {
  const Vec3f& o = scan_.pose.position;
  ASSERT_EQ(scan_.pose.qw, 1.0f);
  {
    std::ofstream xyz(dir_ / "scan.xyz");
    char line[128];
    for (const Vec3f& p : scan_.points) {
      std::snprintf(line, sizeof line, "%.9g %.9g %.9g\n", p.x, p.y, p.z);
      xyz << line;
    }
    std::ofstream cov(dir_ / "cov.txt");  // x, y, yaw: diag(0.05^2, 0.05^2, 0.02^2)
    std::snprintf(line, sizeof line, "0 %.9g %.9g %.9g 0 0 0 1 ", o.x, o.y, o.z);
    cov << line << "0.0025 0 0 0 0.0025 0 0 0 0.0004\n";
  }
  const std::string flags = "--backend cpu --max-range 2.5";
  const nlohmann::json plain = station_keeping("bgkl", "1,2", flags);
  char origin[96];
  std::snprintf(origin, sizeof origin, " --origin %.9g,%.9g,%.9g", o.x, o.y, o.z);
  const std::string json = (dir_ / "xyz.json").string();
  Result r = run("station-keeping -q " + (dir_ / "scan.xyz").string() + cell_args_ + " --repeats 1,2 --methods bgkl --json " +
                 json + " " + flags + origin);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(nlohmann::json::parse(std::ifstream(json))["methods"][0]["cells"], plain);

  const nlohmann::json with_sigma = station_keeping("bgkl", "1,2", flags + " --pose-sigma 0.05,0.02");
  const nlohmann::json with_file = station_keeping("bgkl", "1,2", flags + " --pose-covariance " + (dir_ / "cov.txt").string());
  EXPECT_NE(with_sigma, plain);
  for (const auto& [name, point] : cells_)
    for (size_t k = 0; k < 2; ++k)
      for (const char* v : {"alpha", "beta"})
        EXPECT_NEAR(with_file[name][k][v].get<double>(), with_sigma[name][k][v].get<double>(),
                    1e-9 * with_sigma[name][k][v].get<double>()) << name << " " << v;
  r = run("station-keeping -q " + (dir_ / "scan.pcd").string() + " --cell a:0,0,0 --methods bgkl --json " + json +
          " --pose-sigma 0.05,0.02 --pose-covariance " + (dir_ / "cov.txt").string());
  EXPECT_NE(r.status, 0);  // the file's covariance would take the place of the sigma
  EXPECT_NE(r.output.find("--poses with covariances), not both"), std::string::npos) << r.output;
  r = run("station-keeping -q " + (dir_ / "scan.pcd").string() + " --cell a:0,0,0 --methods octomap --json " + json +
          " --pose-covariance " + (dir_ / "cov.txt").string());
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("octomap does not use a pose uncertainty"), std::string::npos) << r.output;
}

TEST_F(StationKeeping, RefusesAScanFileHoldingSeveralScans) {
  std::filesystem::create_directories(dir_ / "two");
  std::filesystem::copy(dir_ / "scan.pcd", dir_ / "two" / "a.pcd");
  std::filesystem::copy(dir_ / "scan.pcd", dir_ / "two" / "b.pcd");
  const Result r = run("station-keeping -q " + (dir_ / "two").string() + " --cell a:0,0,0 --json " +
                       (dir_ / "x.json").string());
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.output.find("more than one scan"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace bgkmap
