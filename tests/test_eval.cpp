// Scoring (src/eval): metrics on hand-computed cases, the held-out split, refusal of mismatched
// truth, BGK-L scored end to end on a small simulated scene, and `bgkmap eval` on every method's
// maps (.bgk beside .ot) and with --method / --methods on held-out beams against the methods'
// plain references (a Mapper, liboctomap called directly).
#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/metrics.hpp"
#include "bgkmap/eval/plot.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/eval/truth.hpp"
#include "bgkmap/eval/update_sequence.hpp"
#include "bgkmap/integrate/cpu_integrator.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/sim/raycaster.hpp"
#include "bgkmap/sim/scanner.hpp"
#include "bgkmap/sim/simulate.hpp"
#include "bgkmap/sim/spec.hpp"
#include "bgkmap/sim/truth.hpp"
#include "support/test_support.hpp"

namespace bgkmap::eval {
namespace {

constexpr double kTol = 1e-12;

TEST(Metrics, PerfectRankingGivesAucOne) {
  const LabelledScores s{{0.9, 0.8, 0.7}, {0.1, 0.2, 0.3, 0.69}};
  EXPECT_NEAR(roc_auc(s), 1.0, kTol);
  EXPECT_NEAR(average_precision(s), 1.0, kTol);
}

TEST(Metrics, InvertedRankingGivesAucZero) {
  const LabelledScores s{{0.1, 0.2}, {0.8, 0.9, 0.95}};
  EXPECT_NEAR(roc_auc(s), 0.0, kTol);
}

TEST(Metrics, AllTiedGivesAucHalf) {
  const LabelledScores s{{0.5, 0.5, 0.5}, {0.5, 0.5}};
  EXPECT_NEAR(roc_auc(s), 0.5, kTol);
  // One threshold: recall 1 at precision 3/5.
  EXPECT_NEAR(average_precision(s), 0.6, kTol);
}

TEST(Metrics, SmallCaseWithTiesByHand) {
  // Pairs (pos, neg): (.9,.5)=1 (.9,.1)=1 (.5,.5)=1/2 (.5,.1)=1 -> 3.5 / 4.
  const LabelledScores s{{0.9, 0.5}, {0.5, 0.1}};
  EXPECT_NEAR(roc_auc(s), 0.875, kTol);
  // Thresholds .9: recall 1/2 at precision 1; .5: recall 1 at precision 2/3.
  EXPECT_NEAR(average_precision(s), 0.5 * 1.0 + 0.5 * (2.0 / 3.0), kTol);
  const double nll = -(std::log(0.9) + std::log(0.5) + std::log(1 - 0.5) + std::log(1 - 0.1)) / 4;
  EXPECT_NEAR(mean_nll(s), nll, kTol);
  const BinaryMetrics m = compute_metrics(s, 0.7);
  EXPECT_EQ(m.n_positive, 2u);
  EXPECT_EQ(m.n_negative, 2u);
  EXPECT_NEAR(m.accuracy, 0.75, kTol);  // .9 predicted occupied, .5 / .5 / .1 free
  EXPECT_NEAR(m.precision, 1.0, kTol);
  EXPECT_NEAR(m.recall, 0.5, kTol);
  const Curves c = compute_curves(s);
  EXPECT_EQ(c.fpr, (std::vector<double>{0, 0, 0.5, 1}));
  EXPECT_EQ(c.tpr, (std::vector<double>{0, 0.5, 1, 1}));
}

TEST(Metrics, NllClampsCertainMistakes) {
  const LabelledScores s{{0.0}, {1.0}};
  EXPECT_NEAR(mean_nll(s), -std::log(kNllClamp), 1e-9);
  EXPECT_TRUE(std::isfinite(mean_nll(s)));
}

TEST(Metrics, EmptyClassGivesUndefinedAuc) {
  EXPECT_TRUE(std::isnan(roc_auc({{0.4}, {}})));
  EXPECT_TRUE(std::isnan(compute_metrics({{}, {0.2}}, 0.7).precision));
}

TEST(Holdout, SplitIsDisjointCompleteAndReproducible) {
  const size_t n = 20000;
  const BeamSplit a = split_beams(n, 0.1, 7, 3);
  std::set<uint32_t> all(a.kept.begin(), a.kept.end());
  for (uint32_t i : a.held_out) EXPECT_TRUE(all.insert(i).second) << "beam " << i << " both kept and held out";
  EXPECT_EQ(all.size(), n);
  EXPECT_EQ(*all.rbegin(), n - 1);
  // Bernoulli(0.1) over 20000 beams: 2000 +- 42 (1 sigma); allow 5 sigma.
  EXPECT_NEAR(static_cast<double>(a.held_out.size()), 2000.0, 212.0);
  const BeamSplit again = split_beams(n, 0.1, 7, 3);
  EXPECT_EQ(again.held_out, a.held_out);
  EXPECT_NE(split_beams(n, 0.1, 8, 3).held_out, a.held_out);  // another seed
  EXPECT_NE(split_beams(n, 0.1, 7, 4).held_out, a.held_out);  // another scan
  EXPECT_TRUE(split_beams(n, 0.0, 7, 3).held_out.empty());
  EXPECT_TRUE(split_beams(n, 1.0, 7, 3).kept.empty());
  EXPECT_THROW(split_beams(n, 1.5, 7, 3), std::invalid_argument);
}

TEST(Holdout, SamplesHitsAsOccupiedAndBeamsAsFree) {
  BuildParams params;
  params.grid.resolution_m = 0.1;
  // Each sample scored by its x coordinate, so that the positions can be checked too.
  const PointScore score_x = [](double x, double, double) { return x; };
  Scan held;
  held.pose.position = {0, 0, 0};
  held.points = {{1.0f, 0, 0}, {NAN, 0, 0}};
  LabelledScores scores;
  EXPECT_EQ(add_holdout_samples(held, params.preprocess, 0.1, score_x, scores), 1u);
  ASSERT_EQ(scores.positive.size(), 1u);
  EXPECT_NEAR(scores.positive[0], 1.0, 1e-7);
  ASSERT_EQ(scores.negative.size(), 9u);  // 0.1 .. 0.9 m: one spacing short of the hit
  EXPECT_NEAR(scores.negative.front(), 0.1, 1e-7);
  EXPECT_NEAR(scores.negative.back(), 0.9, 1e-7);
  // A return beyond max range: free samples only, up to one spacing short of the max range.
  params.preprocess.max_range_m = 0.5;
  LabelledScores far;
  add_holdout_samples(held, params.preprocess, 0.1, score_x, far);
  EXPECT_TRUE(far.positive.empty());
  EXPECT_EQ(far.negative.size(), 4u);
  // Maps built without such returns are not scored on them either.
  params.preprocess.beyond_range = BeyondRange::kDrop;
  LabelledScores none;
  EXPECT_EQ(add_holdout_samples(held, params.preprocess, 0.1, score_x, none), 0u);
  EXPECT_TRUE(none.positive.empty());
  EXPECT_TRUE(none.negative.empty());
}

TEST(UpdateSequence, MeanTwoSigmaByHand) {
  const MeanTwoSigma s = mean_two_sigma({0.5, NAN, 0.7, 0.9});
  EXPECT_EQ(s.count, 3u);
  EXPECT_NEAR(s.mean, 0.7, kTol);
  EXPECT_NEAR(s.two_sigma, 2 * std::sqrt((0.04 + 0 + 0.04) / 2), kTol);  // sample deviation 0.2
  EXPECT_TRUE(std::isnan(mean_two_sigma({0.4}).two_sigma));
  EXPECT_EQ(mean_two_sigma({NAN}).count, 0u);
}

// The BHM Table 2 protocol on three tiny scans along +x (hits 0.5 m apart, free samples every
// 0.5 m): the map gets each scan's kept beams, and after updates 2 and 3 (every 2, and the last)
// is scored on the held-out samples of every scan so far, listed and scored here by hand (AUC by
// counting pairs, NLL from its definition) with a map whose score changes with each update.
TEST(UpdateSequence, ScoresTheHeldOutBeamsSoFarAfterEachUpdate) {
  std::vector<Scan> scans(3);
  for (size_t k = 0; k < scans.size(); ++k)
    for (int i = 0; i < 8; ++i) scans[k].points.push_back({float(1.0 + 0.5 * i + 0.5 * double(k)), 0, 0});
  UpdateSequenceParams p;
  p.fraction = 0.5;
  p.seed = 3;
  p.spacing = 0.5;
  p.every = 2;
  size_t next = 0, updates = 0;
  std::vector<size_t> inserted;
  const PointScore score = [&](double x, double, double) {
    return 1 / (1 + std::exp(-(x - 2.0 - 0.4 * double(updates)) * (1 + double(updates))));
  };
  const UpdateSequenceResult r = run_update_sequence(
      [&](Scan& scan) { return next < scans.size() ? (scan = scans[next++], true) : false; },
      [&](const Scan& kept) {
        ++updates;
        inserted.push_back(kept.points.size());
      },
      score, p);
  // By hand: scan k's held-out beam i has its hit at x = 1 + 0.5 (i + k), free samples 0.5, 1, .., x - 0.5.
  std::vector<double> auc, nll;
  std::vector<double> pos_x, neg_x;
  size_t held = 0;
  ASSERT_EQ(r.updates.size(), 2u);
  for (size_t k = 0, scored = 0; k < scans.size(); ++k) {
    const BeamSplit split = split_beams(8, 0.5, 3, k);
    EXPECT_EQ(inserted[k], split.kept.size());
    held += split.held_out.size();
    for (uint32_t i : split.held_out) {
      const double hit = 1 + 0.5 * (i + double(k));
      pos_x.push_back(hit);
      for (double x = 0.5; x < hit - 0.25; x += 0.5) neg_x.push_back(x);
    }
    if (k == 0) continue;  // scored after updates 2 and 3
    updates = k + 1;       // the map as it was then
    double pairs = 0, nll_sum = 0;
    for (double a : pos_x) {
      nll_sum -= std::log(score(a, 0, 0));
      for (double b : neg_x) pairs += score(a, 0, 0) > score(b, 0, 0) ? 1.0 : score(a, 0, 0) == score(b, 0, 0) ? 0.5 : 0.0;
    }
    for (double b : neg_x) nll_sum -= std::log(1 - score(b, 0, 0));
    auc.push_back(pairs / double(pos_x.size() * neg_x.size()));
    nll.push_back(nll_sum / double(pos_x.size() + neg_x.size()));
    const UpdateScore& u = r.updates[scored++];
    EXPECT_EQ(u.scans, k + 1);
    EXPECT_EQ(u.metrics.n_positive, pos_x.size());
    EXPECT_EQ(u.metrics.n_negative, neg_x.size());
    EXPECT_NEAR(u.metrics.auc, auc.back(), kTol);
    EXPECT_NEAR(u.metrics.nll, nll.back(), 1e-9);
  }
  EXPECT_EQ(r.scans, 3u);
  EXPECT_EQ(r.held_beams, held);
  EXPECT_EQ(r.kept_beams, 24u - held);
  EXPECT_GT(held, 0u);
  EXPECT_NE(auc[0], auc[1]);
  EXPECT_NEAR(r.auc.mean, (auc[0] + auc[1]) / 2, kTol);
  EXPECT_NEAR(r.auc.two_sigma, 2 * std::abs(auc[0] - auc[1]) / std::sqrt(2.0), 1e-12);
  EXPECT_NEAR(r.nll.mean, (nll[0] + nll[1]) / 2, 1e-9);
  EXPECT_NEAR(r.nll.two_sigma, 2 * std::abs(nll[0] - nll[1]) / std::sqrt(2.0), 1e-9);
}

TEST(ScanHoldout, WholeRunsOfConsecutiveScansAreHeldOut) {
  // 910 scans in runs of 10: 91 runs, round(9.1) = 9 held out, 90 scans.
  const ScanHoldoutParams params{0.1, 10, 1};
  const std::vector<bool> held = split_scans(910, params);
  ASSERT_EQ(held.size(), 910u);
  EXPECT_EQ(std::count(held.begin(), held.end(), true), 90);
  for (size_t run = 0; run < 91; ++run)  // a run is held out whole or not at all
    for (size_t i = run * 10; i < run * 10 + 10; ++i) EXPECT_EQ(held[i], held[run * 10]) << "scan " << i;
  EXPECT_EQ(split_scans(910, params), held);                            // reproducible
  EXPECT_NE(split_scans(910, {0.1, 10, 2}), held);                      // another seed
  EXPECT_EQ(std::count(held.begin(), held.end(), true), 90);
  // The last run may be short; fractions 0 and 1; at least one run for any fraction above 0.
  const std::vector<bool> short_last = split_scans(25, {1.0, 10, 1});
  EXPECT_EQ(std::count(short_last.begin(), short_last.end(), true), 25);
  const std::vector<bool> none = split_scans(25, {0.0, 10, 1});
  EXPECT_EQ(std::count(none.begin(), none.end(), true), 0);
  const std::vector<bool> one = split_scans(25, {0.01, 10, 1});
  EXPECT_GE(std::count(one.begin(), one.end(), true), 5);
  EXPECT_LE(std::count(one.begin(), one.end(), true), 10);
  EXPECT_TRUE(split_scans(0, params).empty());
  EXPECT_THROW(split_scans(10, {1.5, 10, 1}), std::invalid_argument);
  EXPECT_THROW(split_scans(10, {0.1, 0, 1}), std::invalid_argument);
}

TEST(ScanHoldout, PointsAreTheSamplesOfTheHeldOutBeams) {
  PreprocessParams pre;
  pre.max_range_m = 0.55;
  Scan a;
  a.pose.position = {1, 2, 0};
  a.points = {{1.5f, 2, 0}, {1, 4, 0}};  // a hit 0.5 m away; a return beyond the max range
  Scan b;
  b.pose.position = {0, 0, 0};
  b.points = {{0, 0, 0.25f}};
  const LabelledPoints points = holdout_points({a, b}, pre, 0.1);
  // The same samples as add_holdout_samples, scored here by their coordinates.
  LabelledScores direct;
  for (const Scan& s : {a, b})
    add_holdout_samples(s, pre, 0.1, [](double x, double y, double z) { return x + 10 * y + 100 * z; }, direct);
  const LabelledScores scored = score_points(points, [](double x, double y, double z) { return x + 10 * y + 100 * z; });
  ASSERT_EQ(scored.positive.size(), 2u);
  ASSERT_EQ(scored.negative.size(), direct.negative.size());
  EXPECT_EQ(scored.positive, direct.positive);
  EXPECT_EQ(scored.negative, direct.negative);
  // Hit at (1.5, 2): free at 0.1 .. 0.4 m; the 2 m beam is free to 0.45 m (4 samples); (0, 0, 0.25): 0.1 m.
  EXPECT_DOUBLE_EQ(points.occupied[0].x, 1.5);
  ASSERT_EQ(points.free.size(), 4u + 4u + 1u);
  EXPECT_NEAR(points.free[4].y, 2.1, 1e-12);
  EXPECT_NEAR(points.free[7].y, 2.4, 1e-12);
  EXPECT_DOUBLE_EQ(points.occupied[1].z, 0.25);
}

TEST(ScanHoldout, SplitOfASourceKeepsOrderAndIndices) {
  const auto dir = testing::make_temp_dir("scan-holdout");
  std::string log;
  for (int i = 0; i < 23; ++i)  // scan i: one beam of length 1 + i / 100 straight ahead
    log += "FLASER 1 " + std::to_string(1 + i / 100.0) + " " + std::to_string(i) + " 0 1.5707963 0 0 0 " +
           std::to_string(i) + " host " + std::to_string(i) + "\n";
  testing::write_bytes(dir / "a.log", log);
  const ScanHoldoutParams params{0.3, 4, 9};
  const WholeScanSplit split = split_whole_scans({dir / "a.log"}, params);
  const std::vector<bool> held = split_scans(23, params);
  ASSERT_EQ(split.training.size() + split.held_out.size(), 23u);
  ASSERT_EQ(split.held_out.size(), split.held_out_indices.size());
  size_t t = 0, h = 0;
  for (size_t i = 0; i < 23; ++i) {
    const Scan& scan = held[i] ? split.held_out.at(h) : split.training.at(t);
    if (held[i]) EXPECT_EQ(split.held_out_indices[h++], i);
    else ++t;
    EXPECT_FLOAT_EQ(scan.pose.position.x, float(i));  // scan i, in order
  }
  std::filesystem::remove_all(dir);
}

// A small scene: a 1 m box on the ground, scanned by a coarse VLP-16 from three poses.
sim::SimulationSpec tiny_spec() {
  sim::SimulationSpec spec;
  spec.name = "tiny";
  spec.scene.primitives.push_back(sim::Box({2.0, 0.0, 0.5}, {1.0, 1.0, 1.0}));
  spec.scene.primitives.push_back(sim::HalfSpace({0, 0, 0}, {0, 0, 1}));
  spec.scene.bounds = sim::Box3d{{-1, -2, -0.3}, {4, 2, 1.5}};
  spec.sensor = sim::sensor_preset("vlp16");
  spec.sensor.azimuth_resolution_deg = 1.0;
  spec.sensor.max_range_m = 6;
  spec.trajectory.waypoints = {{{0, -1, 0.8}, std::nullopt}, {{0, 1, 0.8}, std::nullopt}};
  spec.trajectory.scans = 3;
  spec.truth_resolution_m = 0.1;
  return spec;
}

BgkMap build_tiny_map(const sim::SimulationSpec& spec, double resolution) {
  BuildParams params;
  params.grid.resolution_m = resolution;
  params.preprocess.downsample_m = 0;
  params.preprocess.max_range_m = spec.sensor.max_range_m;
  params.kernel.ell_m = 0.2f;
  params.kernel.sigma0 = 0.1f;
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  const sim::Raycaster raycaster(spec.scene);
  const auto directions = sim::beam_directions(spec.sensor);
  const auto poses = sim::sample_poses(spec.trajectory);
  sim::ScanCounts counts;
  for (size_t i = 0; i < poses.size(); ++i)
    mapper.insert(sim::simulate_scan(raycaster, spec.sensor, directions, poses[i], spec.seed, i, counts));
  return mapper.map();
}

TEST(TruthEval, BgkLScoresWellOnATinyScene) {
  const auto dir = testing::make_temp_dir("eval");
  const sim::SimulationSpec spec = tiny_spec();
  sim::save_spec(dir / "scene.yaml", spec);
  sim::write_truth_bt(dir / "truth.bt", spec.scene, *spec.scene.bounds, 0.1);
  const std::unique_ptr<ScoredMap> map = make_scored_map(build_tiny_map(spec, 0.1));

  for (const char* truth_file : {"scene.yaml", "truth.bt"}) {
    SCOPED_TRACE(truth_file);
    const auto truth = load_truth(dir / truth_file, map->grid());
    const sim::Box3d observed = map->observed_bounds();
    ASSERT_TRUE(truth->region().overlaps(observed));
    const TruthScores scores = score_against_truth(*map, *truth, observed);
    const BinaryMetrics seen = compute_metrics(scores.observed_cells, 0.7);
    const BinaryMetrics all = compute_metrics(scores.all_cells, 0.7);
    EXPECT_GT(seen.auc, 0.9);
    EXPECT_GT(seen.n_positive, 100u);
    EXPECT_GT(seen.n_negative, 1000u);
    // The all-cells protocol scores a superset of the cells.
    EXPECT_GE(all.n_positive + all.n_negative, seen.n_positive + seen.n_negative);
    EXPECT_GT(all.n_negative, seen.n_negative);
  }
  // The slice and curve figures are written as PNG files.
  const auto truth = load_truth(dir / "scene.yaml", map->grid());
  const SliceImage slice = make_slice(*map, truth.get(), map->observed_bounds(), 0.5);
  EXPECT_TRUE(slice.has_variance);
  EXPECT_EQ(slice.variance.size(), slice.mean.size());
  EXPECT_EQ(slice.truth[static_cast<size_t>(slice.width) * (slice.height / 2) + slice.width / 2] ==
                TruthLabel::kUnknown,
            false);
  write_slice_png(dir / "slice.png", slice, "tiny");
  write_curves_png(dir / "roc.png", {{"tiny", compute_curves({{0.9, 0.4}, {0.1, 0.5}}), 0.75, 0.83}}, "test");
  for (const char* png : {"slice.png", "roc.png"}) {
    std::ifstream in(dir / png, std::ios::binary);
    char magic[4] = {};
    in.read(magic, 4);
    EXPECT_EQ(std::string(magic + 1, 3), "PNG") << png;
  }
  std::filesystem::remove_all(dir);
}

TEST(TruthEval, TruthAtAnotherResolutionIsRefused) {
  const auto dir = testing::make_temp_dir("eval-res");
  const sim::SimulationSpec spec = tiny_spec();
  sim::write_truth_bt(dir / "truth.bt", spec.scene, *spec.scene.bounds, 0.2);
  BuildParams params;
  params.grid.resolution_m = 0.1;
  const BgkMap map(params);
  try {
    load_truth(dir / "truth.bt", map.grid());
    FAIL() << "a 0.2 m truth was accepted for a 0.1 m map";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("resolution"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("truth.bt"), std::string::npos) << e.what();
  }
  EXPECT_THROW(load_truth(dir / "missing.bt", map.grid()), InputError);
  std::filesystem::remove_all(dir);
}

// Runs `bgkmap ARGS`, returning the exit status and stderr.
int run_cli(const std::string& args, const std::filesystem::path& dir, std::string& err) {
  const auto err_file = dir / "stderr.txt";
  const int status = std::system((std::string(BGKMAP_CLI) + " " + args + " 2> " + err_file.string()).c_str());
  std::ifstream in(err_file);
  std::stringstream text;
  text << in.rdbuf();
  err = text.str();
  return status;
}

TEST(EvalCommand, EndToEndAndRefusals) {
  const auto dir = testing::make_temp_dir("eval-cli");
  sim::SimulationSpec spec = tiny_spec();
  sim::save_spec(dir / "scene.yaml", spec);
  write_native_map(dir / "a.bgk", build_tiny_map(spec, 0.1));
  write_native_map(dir / "b.bgk", build_tiny_map(spec, 0.2));
  const std::string d = dir.string() + "/";
  std::string err;

  ASSERT_EQ(run_cli("eval " + d + "a.bgk --truth " + d + "scene.yaml --json " + d + "e.json --plot " + d + "roc.png",
                    dir, err), 0) << err;
  std::ifstream json(dir / "e.json");
  std::stringstream text;
  text << json.rdbuf();
  for (const char* key : {"\"auc\"", "\"average_precision\"", "\"nll\"", "\"accuracy\"", "\"precision\"",
                          "\"recall\"", "\"n_positive\"", "\"n_negative\"", "\"observed_cells\""})
    EXPECT_NE(text.str().find(key), std::string::npos) << key;
  EXPECT_TRUE(std::filesystem::exists(dir / "roc.png"));

  EXPECT_NE(run_cli("eval " + d + "a.bgk " + d + "b.bgk --truth " + d + "scene.yaml --json " + d + "f.json", dir, err), 0);
  EXPECT_NE(err.find("b.bgk: resolution"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(dir / "f.json"));

  // The same scene 100 m away: a truth in another frame.
  spec.scene.bounds = sim::Box3d{{99, -2, -0.3}, {104, 2, 1.5}};
  sim::save_spec(dir / "far.yaml", spec);
  EXPECT_NE(run_cli("eval " + d + "a.bgk --truth " + d + "far.yaml --json " + d + "g.json", dir, err), 0);
  EXPECT_NE(err.find("does not overlap"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

// Reads a PNG's width and height from its IHDR chunk (0, 0 if it is not a PNG).
std::pair<uint32_t, uint32_t> png_size(const std::filesystem::path& file) {
  const std::string bytes = testing::read_bytes(file);
  if (bytes.size() < 24 || bytes.compare(1, 3, "PNG") != 0 || bytes.compare(12, 4, "IHDR") != 0) return {0, 0};
  const auto be32 = [&](size_t at) {
    uint32_t v = 0;
    for (size_t i = 0; i < 4; ++i) v = (v << 8) | static_cast<unsigned char>(bytes[at + i]);
    return v;
  };
  return {be32(16), be32(20)};
}

// bgkmap render: the map's observed cells on one plane, two panels (mean, variance) without a truth one.
TEST(RenderCommand, DrawsTheObservedCellsOfTheMap) {
  const auto dir = testing::make_temp_dir("render-cli");
  const sim::SimulationSpec spec = tiny_spec();
  write_native_map(dir / "a.bgk", build_tiny_map(spec, 0.1));
  const std::string d = dir.string() + "/";
  std::string err;
  ASSERT_EQ(run_cli("render " + d + "a.bgk -o " + d + "a.png --z 0.25", dir, err), 0) << err;
  const std::unique_ptr<ScoredMap> map = load_scored_map(dir / "a.bgk");
  const sim::Box3d b = map->observed_bounds();
  const int w = int(std::floor(b.max.x / 0.1)) - int(std::floor(b.min.x / 0.1)) + 1;
  const int h = int(std::floor(b.max.y / 0.1)) - int(std::floor(b.min.y / 0.1)) + 1;
  EXPECT_NE(err.find(std::to_string(w) + " x " + std::to_string(h) + " cells at z = 0.250 m"), std::string::npos) << err;
  const SliceLayout layout = slice_layout(make_slice(*map, nullptr, b, 0.25));
  EXPECT_EQ(layout.panels.size(), 2u);  // no truth panel
  EXPECT_EQ(layout.upscale, std::clamp(600 / std::max(w, h), 1, 8));
  EXPECT_EQ(png_size(dir / "a.png"), std::make_pair(uint32_t(layout.width), uint32_t(layout.height)));
  // Without --z: the layer with the most occupied cells continued above and below, said so.
  ASSERT_EQ(run_cli("render " + d + "a.bgk -o " + d + "c.png", dir, err), 0) << err;
  const std::optional<double> z = busiest_layer_z(*map);
  ASSERT_TRUE(z.has_value());
  char expected[64];
  std::snprintf(expected, sizeof expected, "cells at z = %.3f m (the default layer", *z);
  EXPECT_NE(err.find(expected), std::string::npos) << err;
  EXPECT_NE(run_cli("render " + d + "missing.bgk -o " + d + "b.png", dir, err), 0);
  EXPECT_NE(err.find("missing.bgk"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

// The tiny scene's scans as .pcd files in dir/scans.
void write_tiny_scans(const std::filesystem::path& dir) {
  const sim::SimulationSpec spec = tiny_spec();
  const sim::Raycaster raycaster(spec.scene);
  const auto directions = sim::beam_directions(spec.sensor);
  const auto poses = sim::sample_poses(spec.trajectory);
  sim::ScanCounts counts;
  std::filesystem::create_directories(dir / "scans");
  for (size_t i = 0; i < poses.size(); ++i)
    write_pcd(dir / "scans" / sim::scan_file_name(i, poses.size()),
              sim::simulate_scan(raycaster, spec.sensor, directions, poses[i], spec.seed, i, counts));
}

TEST(EvalCommand, HoldoutIsReproducibleWithItsSeed) {
  const auto dir = testing::make_temp_dir("eval-holdout");
  write_tiny_scans(dir);
  const std::string d = dir.string() + "/";
  const std::string flags = " --max-range 6 --backend cpu --threads 2 " + d + "scans --json ";
  std::string err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5" + flags + d + "a.json", dir, err), 0) << err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5" + flags + d + "b.json", dir, err), 0) << err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 6" + flags + d + "c.json", dir, err), 0) << err;
  const std::string a = read_text(dir / "a.json");
  EXPECT_NE(a.find("\"held_out_beams\""), std::string::npos) << a;
  EXPECT_EQ(a, read_text(dir / "b.json"));
  EXPECT_NE(a, read_text(dir / "c.json"));
  // Neither or both of --truth and --holdout: refused.
  EXPECT_NE(run_cli("eval" + flags + d + "d.json", dir, err), 0);
  EXPECT_NE(err.find("exactly one of --truth"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

nlohmann::json read_json(const std::filesystem::path& file) { return nlohmann::json::parse(read_text(file)); }

// --protocol bhm-table2 on the tiny scans: an entry per update, and the last update (the whole
// map, every scan's held-out beams) scores exactly as --holdout 0.1 --split beams does.
TEST(EvalCommand, BhmTable2ProtocolEndsAtThePerBeamHoldout) {
  const auto dir = testing::make_temp_dir("eval-protocol");
  write_tiny_scans(dir);
  const std::string d = dir.string() + "/";
  const std::string flags = " --max-range 6 --backend cpu --threads 2 -q " + d + "scans --json ";
  std::string err;
  ASSERT_EQ(run_cli("eval --protocol bhm-table2 --seed 5" + flags + d + "p.json", dir, err), 0) << err;
  ASSERT_EQ(run_cli("eval --holdout 0.1 --seed 5" + flags + d + "h.json", dir, err), 0) << err;
  const nlohmann::json p = read_json(dir / "p.json"), h = read_json(dir / "h.json");
  const nlohmann::json& updates = p["updates"];
  ASSERT_EQ(updates.size(), p["holdout"]["scans"].get<size_t>());
  ASSERT_GE(updates.size(), 2u);
  const nlohmann::json& last = updates.back();
  EXPECT_EQ(last["scans"], p["holdout"]["scans"]);
  EXPECT_EQ(p["holdout"]["held_out_beams"], h["holdout"]["held_out_beams"]);
  EXPECT_EQ(last["n_positive"], h["n_positive"]);
  EXPECT_EQ(last["n_negative"], h["n_negative"]);
  EXPECT_DOUBLE_EQ(last["auc"].get<double>(), h["auc"].get<double>());
  EXPECT_DOUBLE_EQ(last["nll"].get<double>(), h["nll"].get<double>());
  EXPECT_GT(p["auc"]["updates"].get<int>(), 0);
  // Not the protocol's split, or not one method: refused in one line.
  EXPECT_NE(run_cli("eval --protocol bhm-table2 --holdout 0.2" + flags + d + "x.json", dir, err), 0);
  EXPECT_NE(err.find("holds out 10 %"), std::string::npos) << err;
  EXPECT_NE(run_cli("eval --protocol bhm-table2 --split scans" + flags + d + "x.json", dir, err), 0);
  EXPECT_NE(err.find("--split scans is not its protocol"), std::string::npos) << err;
  EXPECT_NE(run_cli("eval --protocol bhm-table2 --methods bgkl,octomap" + flags + d + "x.json", dir, err), 0);
  EXPECT_NE(err.find("one --method"), std::string::npos) << err;
  EXPECT_NE(run_cli("eval --holdout 0.1 --score-every 2" + flags + d + "x.json", dir, err), 0);
  EXPECT_NE(err.find("--score-every needs --protocol"), std::string::npos) << err;
  std::filesystem::remove_all(dir);
}

// The held-out protocol written out: the scans read as the CLI reads them, each split by the same
// hash, `insert_kept` given the kept beams, the held-out beams' samples scored by `score`.
LabelledScores direct_holdout_scores(const std::filesystem::path& scans, double fraction, uint64_t seed,
                                     const PreprocessParams& preprocess,
                                     const std::function<void(const Scan& kept)>& insert_kept,
                                     const std::function<PointScore()>& make_score) {
  ScanSource source({scans});
  std::vector<Scan> held_out;
  Scan scan;
  for (uint64_t index = 0; source.next(scan); ++index) {
    const BeamSplit split = split_beams(scan.points.size(), fraction, seed, index);
    insert_kept(select_beams(scan, split.kept));
    held_out.push_back(select_beams(scan, split.held_out));
  }
  const PointScore score = make_score();
  LabelledScores out;
  for (const Scan& s : held_out) add_holdout_samples(s, preprocess, 0.1, score, out);
  return out;
}

void expect_metrics_equal(const nlohmann::json& j, const BinaryMetrics& m) {
  EXPECT_EQ(j["auc"].get<double>(), m.auc);
  EXPECT_EQ(j["average_precision"].get<double>(), m.average_precision);
  EXPECT_EQ(j["nll"].get<double>(), m.nll);
  EXPECT_EQ(j["accuracy"].get<double>(), m.accuracy);
  EXPECT_EQ(j["n_positive"].get<uint64_t>(), m.n_positive);
  EXPECT_EQ(j["n_negative"].get<uint64_t>(), m.n_negative);
}

TEST(EvalCommand, HoldoutDefaultIsBgklScoredAsBefore) {
  const auto dir = testing::make_temp_dir("eval-holdout-bgkl");
  write_tiny_scans(dir);
  const std::string d = dir.string() + "/";
  std::string err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5 --max-range 6 --backend cpu --threads 2 " + d + "scans --json " + d +
                        "a.json", dir, err), 0) << err;

  // Before --method: a Mapper on the kept beams, every sample scored by its posterior mean.
  BuildParams params;
  params.preprocess.max_range_m = 6;
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  const LabelledScores scores = direct_holdout_scores(
      dir / "scans", 0.2, 5, params.preprocess, [&](const Scan& kept) { mapper.insert(kept); },
      [&] {
        const BgkMap& map = mapper.map();
        return PointScore([&map](double x, double y, double z) { return map.query(x, y, z).mean(); });
      });
  const BinaryMetrics expected = compute_metrics(scores, params.classify.occupied_threshold);
  const nlohmann::json a = read_json(dir / "a.json");
  EXPECT_EQ(a["method"], "bgkl");
  expect_metrics_equal(a, expected);
  EXPECT_GT(expected.auc, 0.9);
  std::filesystem::remove_all(dir);
}

// --split scans on the Intel log: the CLI's figures are those of split_whole_scans, a Mapper on
// the training scans and the held-out scans' samples scored by its posterior mean.
TEST(EvalCommand, WholeScanHoldoutOnTheIntelLogEqualsTheDirectSplit) {
  BGKMAP_REQUIRE_DATASETS(datasets);
  const auto dir = testing::make_temp_dir("eval-scan-holdout");
  const std::filesystem::path intel = datasets / "carmen/intel-corrected.log.gz";
  const std::string d = dir.string() + "/";
  std::string err;
  ASSERT_EQ(run_cli("eval --holdout 0.1 --split scans --run-length 10 --seed 3 " + intel.string() +
                        " --max-range 20 --backend cpu --threads 2 --json " + d + "a.json",
                    dir, err),
            0)
      << err;
  BuildParams params;
  params.preprocess.max_range_m = 20;
  const WholeScanSplit split = split_whole_scans({intel}, {0.1, 10, 3});
  EXPECT_EQ(split.held_out.size(), 90u);
  Mapper mapper(params, std::make_unique<CpuIntegrator>(2));
  for (const Scan& scan : split.training) mapper.insert(scan);
  const BgkMap& map = mapper.map();
  const LabelledScores scores = score_points(holdout_points(split.held_out, params.preprocess, 0.1),
                                             [&map](double x, double y, double z) { return map.query(x, y, z).mean(); });
  const BinaryMetrics expected = compute_metrics(scores, params.classify.occupied_threshold);
  const nlohmann::json a = read_json(dir / "a.json");
  EXPECT_EQ(a["holdout"]["split"], "scans");
  EXPECT_EQ(a["holdout"]["held_out_scans"].get<int>(), 90);
  EXPECT_EQ(a["holdout"]["held_out_beams"].get<int>(), 90 * 180);
  expect_metrics_equal(a, expected);
  EXPECT_GT(expected.auc, 0.95);
  // --split needs --holdout.
  EXPECT_NE(run_cli("eval " + d + "m.bgk --truth x.yaml --split scans --json " + d + "b.json", dir, err), 0);
  EXPECT_NE(err.find("--split and --run-length need --holdout"), std::string::npos) << err;
  // Build flags build maps: with --truth they were ignored (the map's own threshold was used).
  for (const char* flag : {"--occupied-threshold 0.5", "--ell 0.3", "--backend cpu"}) {
    EXPECT_NE(run_cli("eval " + d + "m.bgk --truth x.yaml " + flag + " --json " + d + "b.json", dir, err), 0) << flag;
    EXPECT_NE(err.find(std::string(flag).substr(0, std::string(flag).find(' ')) + " is a build flag: with --truth"),
              std::string::npos) << err;
  }
  std::filesystem::remove_all(dir);
}

TEST(EvalCommand, HoldoutOctomapEqualsLiboctomapDirectly) {
  const auto dir = testing::make_temp_dir("eval-holdout-octomap");
  write_tiny_scans(dir);
  const std::string d = dir.string() + "/";
  const std::string flags = " --max-range 6 --ds 0 --backend cpu --threads 2 " + d + "scans --json " + d;
  std::string err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5 --method octomap" + flags + "o.json", dir, err), 0) << err;

  // liboctomap itself on the kept beams (finite points, origin = the sensor, max range 6 m).
  octomap::OcTree tree(0.1);
  PreprocessParams preprocess;
  preprocess.max_range_m = 6;
  const LabelledScores scores = direct_holdout_scores(
      dir / "scans", 0.2, 5, preprocess,
      [&](const Scan& kept) {
        octomap::Pointcloud cloud;
        for (const Vec3f& p : kept.points)
          if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)) cloud.push_back(p.x, p.y, p.z);
        const Vec3f& o = kept.pose.position;
        if (cloud.size() > 0) tree.insertPointCloud(cloud, octomap::point3d(o.x, o.y, o.z), 6.0);
      },
      [&] {
        return PointScore([&tree](double x, double y, double z) {
          const octomap::OcTreeNode* node = tree.search(x, y, z);
          return node ? node->getOccupancy() : 0.5;
        });
      });
  const BinaryMetrics expected = compute_metrics(scores, tree.getOccupancyThres());
  const nlohmann::json o = read_json(dir / "o.json");
  EXPECT_EQ(o["method"], "octomap");
  EXPECT_EQ(o["occupied_threshold"].get<double>(), 0.5);
  expect_metrics_equal(o, expected);
  EXPECT_GT(expected.auc, 0.88);  // 0.902 when written; chance is 0.5
  EXPECT_GT(expected.n_positive, 200u);

  // Several methods on one split: each entry is that method's run alone; a typo is refused first.
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5 --methods bgkl,octomap" + flags + "m.json --plot " + d + "m.png",
                    dir, err), 0) << err;
  ASSERT_EQ(run_cli("eval --holdout 0.2 --seed 5" + flags + "a.json", dir, err), 0) << err;
  const nlohmann::json m = read_json(dir / "m.json");
  ASSERT_EQ(m["methods"].size(), 2u);
  EXPECT_EQ(m["methods"][0]["method"], "bgkl");
  EXPECT_EQ(m["methods"][0]["auc"], read_json(dir / "a.json")["auc"]);
  EXPECT_EQ(m["methods"][1]["auc"], o["auc"]);
  EXPECT_EQ(m["methods"][1]["n_negative"], o["n_negative"]);
  EXPECT_TRUE(std::filesystem::exists(dir / "m.png"));
  EXPECT_NE(run_cli("eval --holdout 0.2 --methods bgkl,octomap --method bgk" + flags + "x.json", dir, err), 0);
  EXPECT_NE(err.find("not both"), std::string::npos) << err;
  EXPECT_NE(run_cli("eval --holdout 0.2 --methods bgkl,octomapp" + flags + "x.json", dir, err), 0);
  EXPECT_NE(err.find("unknown method 'octomapp'"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.json"));
  std::filesystem::remove_all(dir);
}

TEST(EvalCommand, ScoresOctomapTreesBesideBgkMaps) {
  const auto dir = testing::make_temp_dir("eval-cli-trees");
  const sim::SimulationSpec spec = tiny_spec();
  sim::save_spec(dir / "scene.yaml", spec);
  const BgkMap map = build_tiny_map(spec, 0.1);
  write_native_map(dir / "a.bgk", map);
  write_octomap_tree(dir / "a.ot", map, TreeValues::kMean);
  write_octomap_tree(dir / "coarse.ot", build_tiny_map(spec, 0.2), TreeValues::kMean);
  {
    std::ofstream bad(dir / "bad.ot");
    bad << "# Octomap OcTree file\nid OcTree\nsize 5\nres 0.1\ndata\n\x01";
  }
  const std::string d = dir.string() + "/";
  std::string err;
  ASSERT_EQ(run_cli("eval " + d + "a.bgk " + d + "a.ot --truth " + d + "scene.yaml --json " + d + "t.json --plot " + d +
                        "roc.png", dir, err), 0) << err;
  const nlohmann::json t = read_json(dir / "t.json");
  ASSERT_EQ(t["maps"].size(), 2u);
  const nlohmann::json& bgk = t["maps"][0];
  const nlohmann::json& tree = t["maps"][1];
  // The same cells with evidence, the same counts, scores equal to float log-odds precision.
  for (const char* protocol : {"all_cells", "observed_cells"})
    for (const char* count : {"n_positive", "n_negative"})
      EXPECT_EQ(bgk["protocols"][protocol][count], tree["protocols"][protocol][count]) << protocol << " " << count;
  EXPECT_NEAR(bgk["auc"].get<double>(), tree["auc"].get<double>(), 1e-4);
  EXPECT_NEAR(bgk["nll"].get<double>(), tree["nll"].get<double>(), 1e-5);
  EXPECT_EQ(bgk["occupied_threshold"].get<double>(), static_cast<double>(map.params().classify.occupied_threshold));
  EXPECT_EQ(tree["occupied_threshold"].get<double>(), 0.5);

  // A tree's slice: no variance panel, but it is drawn.
  ASSERT_EQ(run_cli("eval " + d + "a.ot --truth " + d + "scene.yaml --json " + d + "u.json --slice " + d + "slice.png",
                    dir, err), 0) << err;
  EXPECT_TRUE(std::filesystem::exists(dir / "slice.png"));
  // Its outputs are committed together: a slice that fails after the metrics were written
  // (a height beyond the keys' reach) leaves the old metrics and plot in place.
  const std::string u_json = testing::read_bytes(dir / "u.json"), roc = testing::read_bytes(dir / "roc.png");
  EXPECT_NE(run_cli("eval " + d + "a.ot --truth " + d + "scene.yaml --json " + d + "u.json --plot " + d +
                        "roc.png --slice " + d + "slice.png --slice-z 1e30", dir, err), 0);
  EXPECT_NE(err.find("beyond the map's key range"), std::string::npos) << err;
  EXPECT_EQ(testing::read_bytes(dir / "u.json"), u_json);
  EXPECT_EQ(testing::read_bytes(dir / "roc.png"), roc);

  EXPECT_NE(run_cli("eval " + d + "a.bgk " + d + "bad.ot --truth " + d + "scene.yaml --json " + d + "v.json", dir, err), 0);
  EXPECT_NE(err.find("bad.ot: truncated or corrupt"), std::string::npos) << err;
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
  EXPECT_NE(run_cli("eval " + d + "a.bgk " + d + "coarse.ot --truth " + d + "scene.yaml --json " + d + "w.json", dir, err), 0);
  EXPECT_NE(err.find("coarse.ot: resolution"), std::string::npos) << err;
  EXPECT_FALSE(std::filesystem::exists(dir / "v.json"));
  EXPECT_FALSE(std::filesystem::exists(dir / "w.json"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace bgkmap::eval
