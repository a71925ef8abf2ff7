// bgkmap tune (src/tune): the parameter tables, the two disjoint held-out splits, the NLopt search
// on a known optimum, BGK-L's prior from kept kernel sums against brute-force rebuilds in double,
// and the command: tuned no worse than given, its YAML taken by build and eval --config,
// the same seed giving the same bytes, and bad flags refused.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <tuple>

#include "bgkmap/eval/holdout.hpp"
#include "bgkmap/eval/scored_map.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "bgkmap/tune/prior_search.hpp"
#include "bgkmap/tune/prior_sums.hpp"
#include "bgkmap/tune/tunable.hpp"
#include "bgkmap/tune/tune.hpp"
#include "bgkmap/tune/unit_cube_search.hpp"
#include "integrate/brute_force.hpp"
#include "support/test_support.hpp"

namespace bgkmap::tune {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Range of the beam from (ox, oy) at angle a to the walls of the 6 x 6 m room centred at the
// origin or to the round pillar of radius 0.5 m at (1.5, -1.5), whichever is nearer.
double room_range(double ox, double oy, double a) {
  const double dx = std::cos(a), dy = std::sin(a);
  double t = 1e9;
  if (dx > 0) t = std::min(t, (3 - ox) / dx);
  if (dx < 0) t = std::min(t, (-3 - ox) / dx);
  if (dy > 0) t = std::min(t, (3 - oy) / dy);
  if (dy < 0) t = std::min(t, (-3 - oy) / dy);
  const double px = ox - 1.5, py = oy + 1.5, b = px * dx + py * dy, q = px * px + py * py - 0.25;
  const double disc = b * b - q;
  if (disc >= 0 && -b - std::sqrt(disc) > 0) t = std::min(t, -b - std::sqrt(disc));
  return t;
}

// A CARMEN log of `scans` scans of 90 beams from poses on a circle of radius 1 m around the
// room's centre, facing along it.
void write_room_log(const std::filesystem::path& file, int scans) {
  std::ofstream out(file);
  for (int s = 0; s < scans; ++s) {
    const double phi = 2 * kPi * s / scans, x = std::cos(phi), y = std::sin(phi), theta = phi + kPi / 2;
    out << "FLASER 90";
    for (int i = 0; i < 90; ++i) out << ' ' << room_range(x, y, theta - kPi / 2 + i * kPi / 90);
    out << ' ' << x << ' ' << y << ' ' << theta << ' ' << x << ' ' << y << ' ' << theta << " 0 host 0\n";
  }
}

BuildParams room_params() {
  BuildParams p;
  p.grid.resolution_m = 0.1;
  p.preprocess.max_range_m = 8;
  p.set_planar(0);
  return p;
}

TEST(TuneTables, EveryMethodsRangesAreOrderedAndRoundTrip) {
  BuildParams p = room_params();
  const MethodParams m;
  for (const std::string& method : tunable_methods()) {
    for (const TunableParam& t : tunable_params(method)) {
      const Range r = absolute_range(t, p);
      ASSERT_LT(r.lo, r.hi) << method << " " << t.name;
      for (double u : {0.0, 0.25, 0.5, 1.0})
        EXPECT_NEAR(to_unit(t.log_scale, r, from_unit(t.log_scale, r, u)), u, 1e-12) << t.name;
      EXPECT_EQ(to_unit(t.log_scale, r, r.hi * 10), 1.0);
      BuildParams q = p;
      MethodParams n = m;
      t.set(q, n, 0.5 * (r.lo + r.hi));
      EXPECT_NEAR(t.get(q, n), 0.5 * (r.lo + r.hi), 1e-6 * r.hi) << t.name;
      // A method parameter is the schema's, by its keyword, and searched within the schema's range.
      if (const ParamSpec* spec = find_method_param(t.name)) {
        EXPECT_EQ(spec->keyword(), t.name);
        EXPECT_TRUE(find_method(method)->reads(spec->key)) << method << " " << t.name;
        EXPECT_TRUE(spec->accepts(r.lo) && spec->accepts(r.hi)) << t.name;
      }
    }
  }
  // Lengths scale with the resolution: l searched over 1 to 10 cells.
  const Range ell = absolute_range(tunable_params("bgkl")[0], p);
  EXPECT_DOUBLE_EQ(ell.lo, 0.1);
  EXPECT_DOUBLE_EQ(ell.hi, 1.0);
  EXPECT_THROW(tunable_params("nonesuch"), std::invalid_argument);
  EXPECT_EQ(tunable_methods(), method_names());  // every method bgkmap ships
}

TEST(TuneSplit, TwoDisjointHeldOutSetsAndTheRestForTraining) {
  const testing::TempDir dir("tune-split");
  write_room_log(dir / "room.log", 40);
  const std::vector<Scan> scans = testing::read_all_scans({dir / "room.log"});
  ASSERT_EQ(scans.size(), 40u);
  // Beams: every beam in exactly one set; the search set is what eval --holdout holds out.
  const TuneSplit beams = split_for_tuning(scans, {0.2, SplitKind::kBeams, 10, 3});
  size_t search = 0, confirm = 0, training = 0;
  for (size_t i = 0; i < scans.size(); ++i) {
    const eval::BeamSplit eval_split = eval::split_beams(90, 0.2, 3, i);
    EXPECT_EQ(beams.search[i].points.size(), eval_split.held_out.size());
    std::multiset<std::tuple<float, float>> all, parts;
    for (const Vec3f& q : scans[i].points) all.insert({q.x, q.y});
    for (const auto* set : {&beams.search, &beams.confirm, &beams.training})
      for (const Vec3f& q : (*set)[i].points) parts.insert({q.x, q.y});
    EXPECT_EQ(all, parts) << "scan " << i;
    search += beams.search[i].points.size();
    confirm += beams.confirm[i].points.size();
    training += beams.training[i].points.size();
  }
  EXPECT_GT(search, 0.15 * 3600);
  EXPECT_LT(search, 0.25 * 3600);
  EXPECT_GT(confirm, 0.15 * 3600);
  EXPECT_LT(confirm, 0.25 * 3600);
  EXPECT_EQ(search + confirm + training, 3600u);
  // Whole scans: runs of 5, each scan in one set, the search's as eval's split_scans.
  const TuneSplit runs = split_for_tuning(scans, {0.2, SplitKind::kScans, 5, 3});
  const std::vector<bool> held = eval::split_scans(40, {0.2, 5, 3});
  EXPECT_EQ(runs.search.size(), size_t(std::count(held.begin(), held.end(), true)));
  EXPECT_EQ(runs.search.size(), 10u);
  EXPECT_EQ(runs.confirm.size(), 10u);
  EXPECT_EQ(runs.training.size(), 20u);
  std::set<float> seen;
  for (const auto* set : {&runs.search, &runs.confirm, &runs.training})
    for (const Scan& s : *set) EXPECT_TRUE(seen.insert(s.pose.position.x * 100 + s.pose.position.y).second);
  // Out of range.
  EXPECT_THROW(split_for_tuning(scans, {0.0, SplitKind::kBeams, 10, 1}), std::invalid_argument);
  EXPECT_THROW(split_for_tuning(scans, {0.5, SplitKind::kBeams, 10, 1}), std::invalid_argument);
  EXPECT_THROW(split_for_tuning(scans, {0.1, SplitKind::kScans, 0, 1}), std::invalid_argument);
  // An even subset for the search's builds.
  const std::vector<Scan> some = spread_subset(runs.training, 4);
  ASSERT_EQ(some.size(), 4u);
  EXPECT_EQ(some[1].pose.position.x, runs.training[5].pose.position.x);
  EXPECT_EQ(spread_subset(runs.training, 0).size(), 20u);
}

TEST(UnitCubeSearch, FindsAKnownMinimumReproduciblyWithinItsBudget) {
  std::vector<std::vector<double>> points;
  const UnitObjective f = [&](const std::vector<double>& x, const std::string& phase) {
    points.push_back(x);
    return std::pow(x[0] - 0.3, 2) + 2 * std::pow(x[1] - 0.8, 2) + 0.1;
  };
  SearchBudget budget;
  budget.evaluations = 40;
  const SearchResult r = minimise_in_unit_cube(f, {0.5, 0.5}, budget);
  EXPECT_LE(r.evaluations, 40u);
  EXPECT_EQ(points.size(), r.evaluations);
  EXPECT_NEAR(r.best[0], 0.3, 1e-3);
  EXPECT_NEAR(r.best[1], 0.8, 1e-3);
  EXPECT_NEAR(r.value, 0.1, 1e-6);
  const std::vector<std::vector<double>> first = points;
  points.clear();
  minimise_in_unit_cube(f, {0.5, 0.5}, budget);
  EXPECT_EQ(points, first);
  // A minimum on the boundary, in 1-D.
  const SearchResult edge = minimise_in_unit_cube(
      [](const std::vector<double>& x, const std::string&) { return 1 - x[0]; }, {0.2}, budget);
  EXPECT_NEAR(edge.best[0], 1.0, 1e-3);
  // Errors propagate.
  EXPECT_THROW(minimise_in_unit_cube([](const std::vector<double>&, const std::string&) -> double {
                 throw std::runtime_error("boom");
               }, {0.5}, budget),
               std::runtime_error);
}

// The held-out samples of the room's search split scored by brute-force posteriors (double) of
// the training scans' observations, one per cell.
class RoomBrute {
 public:
  RoomBrute(const std::vector<Scan>& training, const BuildParams& params)
      : obs_(testing::observations_of(training, params)), params_(params), grid_(params.grid) {}
  CellPosterior operator()(double x, double y, double) {
    const CellIndex c = grid_.cell_of(x, y, params_.preprocess.plane_z_m);
    const auto key = std::make_tuple(c.x, c.y, c.z);
    auto it = cache_.find(key);
    if (it == cache_.end()) it = cache_.emplace(key, brute_force_cell(grid_.cell_center_d(c), obs_, params_)).first;
    const BruteForcePosterior& b = it->second;
    return {b.alpha, b.beta, b.alpha != params_.prior.alpha0 || b.beta != params_.prior.beta0};
  }

 private:
  std::vector<ScanObservations> obs_;
  BuildParams params_;
  Grid grid_;
  std::map<std::tuple<int32_t, int32_t, int32_t>, BruteForcePosterior> cache_;
};

double brute_nll(const std::vector<Scan>& training, const eval::LabelledPoints& points, const BuildParams& params) {
  RoomBrute brute(training, params);
  const eval::PointScore score = [&](double x, double y, double z) {
    const CellPosterior c = brute(x, y, z);
    return c.has_evidence ? c.alpha / (c.alpha + c.beta) : eval::kUnknownScore;
  };
  return eval::mean_nll(eval::score_points(points, score));
}

TEST(PriorFromSums, TheInnerOptimumIsWhatARebuildScores) {
  const testing::TempDir dir("tune-sums");
  write_room_log(dir / "room.log", 24);
  const TuneSplit split = split_for_tuning(testing::read_all_scans({dir / "room.log"}), {0.1, SplitKind::kBeams, 10, 2});
  BuildParams params = room_params();
  params.kernel.ell_m = 0.3f;
  const eval::LabelledPoints points = eval::holdout_points(split.search, params.preprocess, 0.1);
  ASSERT_GT(points.occupied.size(), 100u);
  RoomBrute brute(split.training, params);
  const HeldOutSums sums =
      held_out_sums(points, std::ref(brute), params.kernel.sigma0, params.prior.alpha0, params.prior.beta0);
  const Range range{1e-6 * params.kernel.sigma0, 10.0 * params.kernel.sigma0};
  const PriorParams best = best_prior(sums, params.kernel.sigma0, params.prior, range, range, Objective::kNll);
  const double inner = eval::mean_nll(scores_from_sums(sums, params.kernel.sigma0, best.alpha0, best.beta0));

  BuildParams rebuilt = params;
  rebuilt.prior = best;
  const double rebuild = brute_nll(split.training, points, rebuilt);
  EXPECT_NEAR(inner, rebuild, 1e-9 * rebuild);
  // It is a minimum: the given prior rebuilt scores worse, and so do priors either side of the
  // optimum within the range (this noise-free room wants the smallest prior the range allows).
  EXPECT_LT(rebuild, brute_nll(split.training, points, params));
  for (const float f : {0.5f, 2.0f}) {
    for (float PriorParams::*field : {&PriorParams::alpha0, &PriorParams::beta0}) {
      BuildParams other = rebuilt;
      other.prior.*field *= f;
      if (other.prior.*field < range.lo || other.prior.*field > range.hi) continue;
      EXPECT_LE(rebuild, brute_nll(split.training, points, other) * (1 + 1e-12)) << f;
    }
  }
  EXPECT_FLOAT_EQ(best.alpha0, float(range.lo));
  // Linear in sigma0: another sigma0 from the same sums, against its own rebuild.
  BuildParams scaled = rebuilt;
  scaled.kernel.sigma0 = 0.37f;
  const double from_sums = eval::mean_nll(scores_from_sums(sums, 0.37f, best.alpha0, best.beta0));
  EXPECT_NEAR(from_sums, brute_nll(split.training, points, scaled), 1e-9 * from_sums);

  // The sums a float build (BGK-L on the CPU) keeps agree with the double reference.
  std::unique_ptr<MappingMethod> method = make_method("bgkl", params, {}, testing::cpu_backend());
  for (const Scan& s : split.training) method->insert(s);
  method->finish();
  const PosteriorAt built = [&](double x, double y, double z) {
    const std::optional<CellEstimate> e = method->estimate(x, y, method->query_z(z));
    return e && e->beta ? *e->beta : CellPosterior{};
  };
  const HeldOutSums float_sums = held_out_sums(points, built, params.kernel.sigma0, params.prior.alpha0, params.prior.beta0);
  const double float_inner = eval::mean_nll(scores_from_sums(float_sums, params.kernel.sigma0, best.alpha0, best.beta0));
  EXPECT_NEAR(float_inner, inner, 1e-5 * inner);
}

TuneOptions room_options() {
  TuneOptions o;
  o.params = room_params();
  o.backend = testing::cpu_backend();
  o.split = {0.1, SplitKind::kBeams, 10, 1};
  o.budget = 6;
  return o;
}

TEST(Tune, BgklTunedIsNoWorseThanGivenAndMendsABadPrior) {
  const testing::TempDir dir("tune-bgkl");
  write_room_log(dir / "room.log", 24);
  const std::vector<Scan> scans = testing::read_all_scans({dir / "room.log"});
  TuneOptions o = room_options();
  o.params.prior = {0.5f, 0.5f};  // a prior as heavy as five hits: a poor given value
  const TuneResult r = tune(scans, o);
  ASSERT_EQ(r.names, (std::vector<std::string>{"ell", "prior_alpha", "prior_beta"}));
  EXPECT_LE(r.trials.size(), 6u);
  EXPECT_EQ(r.trials.front().phase, "start");
  EXPECT_DOUBLE_EQ(r.trials.front().values[0], 0.2);  // the given l first
  EXPECT_LT(r.tuned_scores.search.nll, r.given_scores.search.nll);
  EXPECT_LT(r.tuned_scores.confirm.nll, 0.8 * r.given_scores.confirm.nll);
  EXPECT_LT(r.chosen[1], 0.5);
  EXPECT_EQ(r.params.prior.alpha0, float(r.chosen[1]));
  // The best trial's score is the chosen parameters' on the search split (all training scans).
  double best = 1e300;
  for (const Trial& t : r.trials) best = std::min(best, t.objective);
  EXPECT_NEAR(best, r.tuned_scores.search.nll, 1e-5 * best);
  EXPECT_EQ(r.training_scans, 24u);
  EXPECT_EQ(r.search_training_scans, 24u);
}

TEST(Tune, CountingChoosesItsPriorFromOneBuildAndBgkSearchesItsLengthAndSpacing) {
  const testing::TempDir dir("tune-beta");
  write_room_log(dir / "room.log", 24);
  const std::vector<Scan> scans = testing::read_all_scans({dir / "room.log"});
  TuneOptions o = room_options();
  o.method = "counting";
  o.params.prior = {2.0f, 2.0f};  // as heavy as two hits: a poor given value
  o.search_scans = 1e300;         // more than there are: all of them
  TuneResult r = tune(scans, o);
  EXPECT_EQ(r.search_training_scans, r.training_scans);
  ASSERT_EQ(r.names, (std::vector<std::string>{"prior_alpha", "prior_beta"}));
  EXPECT_EQ(r.trials.size(), 1u);  // nothing to rebuild for
  EXPECT_LT(r.chosen[0], 2.0);
  EXPECT_LT(r.tuned_scores.search.nll, r.given_scores.search.nll);
  EXPECT_LT(r.tuned_scores.confirm.nll, r.given_scores.confirm.nll);
  // The trial's score from the sums is what a build with the chosen prior scores.
  EXPECT_NEAR(r.trials[0].objective, r.tuned_scores.search.nll, 1e-5 * r.tuned_scores.search.nll);

  o.method = "bgk";
  o.search_scans = 0;
  o.params.prior = {0.5f, 0.5f};
  o.budget = 5;
  r = tune(scans, o);
  ASSERT_EQ(r.names, (std::vector<std::string>{"ell", "free_resolution", "prior_alpha", "prior_beta"}));
  EXPECT_LE(r.trials.size(), 5u);
  EXPECT_LT(r.tuned_scores.search.nll, r.given_scores.search.nll);
  EXPECT_DOUBLE_EQ(r.method_params.number("free-resolution"), r.chosen[1]);
}

TEST(Tune, OctomapSearchesItsSensorModelOnASubsetOfScans) {
  const testing::TempDir dir("tune-octomap");
  write_room_log(dir / "room.log", 24);
  TuneOptions o = room_options();
  o.method = "octomap";
  o.budget = 8;
  o.search_scans = 0.5;
  const TuneResult r = tune(testing::read_all_scans({dir / "room.log"}), o);
  EXPECT_EQ(r.search_training_scans, 12u);
  EXPECT_EQ(r.trials.size(), 8u);
  EXPECT_EQ(r.names.size(), 4u);
  // The start trial is the given sensor model on the subset; the best trial is no worse.
  EXPECT_DOUBLE_EQ(r.trials[0].values[0], 0.7);
  double best = 1e300;
  for (const Trial& t : r.trials) best = std::min(best, t.objective);
  EXPECT_LE(best, r.trials[0].objective);
  EXPECT_DOUBLE_EQ(r.method_params.number("prob-hit"), r.chosen[0]);
}

// Runs `bgkmap ARGS`: its exit code and its output (stderr included).
testing::CommandResult bgkmap(const std::string& args) {
  return testing::run_command(std::string(BGKMAP_CLI) + " " + args);
}

TEST(TuneCommand, WritesAConfigThatBuildAndEvalTakeAndTheSameSeedGivesTheSameBytes) {
  const testing::TempDir dir("tune-cli");
  write_room_log(dir / "room.log", 24);
  const std::string d = dir.path().string() + "/";
  const std::string flags = " --2d --max-range 8 --backend cpu --threads 2 --budget 4 " + d + "room.log";
  testing::CommandResult r = bgkmap("tune" + flags + " -o " + d + "a.yaml --report " + d + "a.json --plot " + d + "a.png");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(testing::read_bytes(dir / "a.png").substr(0, 8), "\x89PNG\r\n\x1a\n");  // the picture's pixels: test_pictures
  EXPECT_NE(r.output.find("bgkmap: trial 0 (start): ell 0.2, prior_alpha"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("confirming split"), std::string::npos) << r.output;
  const nlohmann::json report = nlohmann::json::parse(testing::read_bytes(dir / "a.json"));
  EXPECT_EQ(report["method"], "bgkl");
  EXPECT_LE(report["trials"].size(), 4u);
  EXPECT_LE(report["tuned"]["search"]["nll"].get<double>(), report["given"]["search"]["nll"].get<double>() + 1e-12);
  EXPECT_TRUE(report["tuned"]["confirm"]["nll"].is_number());
  const double ell = report["parameters"][0]["chosen"];
  const double alpha = report["parameters"][1]["chosen"];

  // build --config takes it: the map's parameters are the chosen ones.
  r = bgkmap("build -q " + d + "room.log --config " + d + "a.yaml --backend cpu -o " + d + "m.bgk --report " + d + "m.json");
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json built = nlohmann::json::parse(testing::read_bytes(dir / "m.json"));
  EXPECT_EQ(built["params"]["ell"].get<double>(), ell);  // the same shortest decimals
  EXPECT_EQ(built["params"]["prior_alpha"].get<double>(), alpha);
  EXPECT_EQ(built["params"]["max_range"].get<double>(), 8.0);
  EXPECT_EQ(built["params"]["planar"], true);
  // eval --config takes it.
  r = bgkmap("eval --holdout 0.1 " + d + "room.log --config " + d + "a.yaml --backend cpu --json " + d + "e.json");
  ASSERT_EQ(r.status, 0) << r.output;

  // The same seed: the same bytes; another seed: another split.
  ASSERT_EQ(bgkmap("tune -q" + flags + " -o " + d + "b.yaml").status, 0);
  EXPECT_EQ(testing::read_bytes(dir / "a.yaml"), testing::read_bytes(dir / "b.yaml"));
  ASSERT_EQ(bgkmap("tune -q --seed 7" + flags + " -o " + d + "c.yaml").status, 0);
  EXPECT_NE(testing::read_bytes(dir / "a.yaml"), testing::read_bytes(dir / "c.yaml"));
}

TEST(TuneCommand, RefusesBadFlagsInOneLine) {
  const testing::TempDir dir("tune-refuse");
  write_room_log(dir / "room.log", 4);
  const std::string d = dir.path().string() + "/";
  const std::string in = " --2d " + d + "room.log -o " + d + "p.yaml";
  struct Case {
    std::string args, message;
    int code;
  };
  const std::vector<Case> cases = {
      {"--holdout 0.5", "--holdout", 2},      {"--holdout 0", "--holdout", 2},
      {"--budget 0", "--budget", 2},          {"--objective auroc", "--objective", 2},
      {"--time -1", "--time", 2},             {"--search-scans 0", "--search-scans", 2},
      {"--plot p.svg", "tune draws its trials as a PNG picture", 2},
  };
  for (const Case& c : cases) {
    const testing::CommandResult r = bgkmap("tune " + c.args + in);
    EXPECT_EQ(r.status, c.code) << c.args << "\n" << r.output;
    EXPECT_EQ(r.output.rfind("bgkmap: error: ", 0), 0u) << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
  }
  const testing::CommandResult txt = bgkmap("tune --2d " + d + "room.log -o " + d + "p.txt");
  EXPECT_EQ(txt.status, 2) << txt.output;  // a usage error, as every command's output name
  EXPECT_NE(txt.output.find("tune writes a YAML file of parameters; give a name ending in .yaml or .yml"),
            std::string::npos) << txt.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "p.yaml"));
}

}  // namespace
}  // namespace bgkmap::tune
