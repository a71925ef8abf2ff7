// The command line a user types: one value per -o, mistyped names answered with the closest
// known one, output names the command cannot write refused, the method flags' help and types.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <vector>

#include "bgkmap/io/pcd_io.hpp"
#include "cli/commands.hpp"
#include "cli/did_you_mean.hpp"
#include "core/number_text.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

using Result = testing::CommandResult;

Result run(const std::string& args) { return testing::run_command(std::string(BGKMAP_CLI) + " " + args); }

size_t lines(const std::string& text) { return static_cast<size_t>(std::count(text.begin(), text.end(), '\n')); }

// A usage error: exit 2, one line, `bgkmap: error: ` first and `expected` in it.
void expect_usage_error(const std::string& args, const std::string& expected) {
  const Result r = run(args);
  EXPECT_EQ(r.status, 2) << args << "\n" << r.output;
  EXPECT_EQ(r.output.rfind("bgkmap: error: ", 0), 0u) << args << "\n" << r.output;
  EXPECT_EQ(lines(r.output), 1u) << args << "\n" << r.output;
  EXPECT_NE(r.output.find(expected), std::string::npos) << args << "\n" << r.output;
}

class CliUsage : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::make_temp_dir("cli_usage");
    const auto scans = testing::random_scans(5, 2, 150, 1.5f);
    std::filesystem::create_directories(dir_ / "scans");
    for (size_t i = 0; i < scans.size(); ++i) write_pcd(dir_ / "scans" / ("s_" + std::to_string(i + 1) + ".pcd"), scans[i]);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }
  bool exists(const std::string& name) const { return std::filesystem::exists(dir_ / name); }
  std::filesystem::path dir_;
};

// `-o a.bgk scans/ --max-range 8` took scans/ as a second output and said "inputs is required".
TEST_F(CliUsage, OutputFlagTakesOneValueAndTheInputAfterItStaysAnInput) {
  Result r = run("build -q -o " + path("a.bgk") + " " + path("scans") + " --max-range 2 --backend cpu --threads 1");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(exists("a.bgk"));
  r = run("build -q -o " + path("b.bgk") + " " + path("scans") + " -o " + path("b.ot") + " --backend cpu --threads 1");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(exists("b.bgk"));
  EXPECT_TRUE(exists("b.ot"));
  EXPECT_FALSE(exists("scans.bgk"));
  r = run("export -o " + path("a.ply") + " " + path("a.bgk") + " -o " + path("a.pcd"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_TRUE(exists("a.ply"));
  EXPECT_TRUE(exists("a.pcd"));
  // Two names after one -o: the second is an input, as in any other position.
  expect_usage_error("export " + path("a.bgk") + " -o " + path("c.ply") + " " + path("c.pcd"),
                     "not expected: " + path("c.pcd"));
}

// A method flag the chosen method does not read was ignored: an octomap build asked to forget
// built a map that never forgets, exit 0.
TEST_F(CliUsage, AMethodFlagTheMethodDoesNotReadIsRefused) {
  const std::string in = " " + path("scans") + " --max-range 2 --backend cpu --threads 1 -q";
  Result r = run("build --method octomap --forget-half-life 5 -o " + path("o.bt") + in);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_EQ(lines(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("bgkmap: error: --forget-half-life is read by bgkl, bgk, counting, not by --method octomap: it "
                          "would be ignored"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(exists("o.bt"));
  r = run("build --method bgkl --forget-half-life 5 -o " + path("a.bgk") + in);
  EXPECT_EQ(r.status, 0) << r.output;
  // Several methods: a flag one of them reads is taken.
  r = run("eval --holdout 0.2 --methods bgkl,octomap --prob-hit 0.8 --json " + path("e.json") + in);
  EXPECT_EQ(r.status, 0) << r.output;
  r = run("eval --holdout 0.2 --methods bgkl,counting --prob-hit 0.8 --json " + path("f.json") + in);
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("--prob-hit is read by octomap, not by --method bgkl, counting"), std::string::npos) << r.output;
}

// Every flag of every subcommand that collects values takes one per use (-o, --cell, --topic, ...).
TEST(CliCommandLine, EveryRepeatableFlagTakesOneValuePerUse) {
  CLI::App app;
  cli::add_commands(app);
  size_t repeatable = 0;
  for (const CLI::App* cmd : app.get_subcommands([](const CLI::App*) { return true; }))
    for (const CLI::Option* opt : cmd->get_options()) {
      if (!opt->nonpositional() || opt->get_items_expected_max() < CLI::detail::expected_max_vector_size) continue;
      ++repeatable;
      EXPECT_FALSE(opt->get_allow_extra_args()) << cmd->get_name() << " " << opt->get_name();
    }
  EXPECT_GE(repeatable, 8u);  // -o of build, merge, export; --cell, --repeats, --methods (2), --topic (3)
}

TEST(CliCommandLine, AMistypedSubcommandIsNamedWithTheClosestOne) {
  expect_usage_error("biuld scans -o m.bgk", "unknown subcommand 'biuld'; did you mean 'build'?");
  expect_usage_error("ifno m.bgk", "unknown subcommand 'ifno'; did you mean 'info'?");
  expect_usage_error("sim structured -o out", "did you mean 'simulate'?");
  expect_usage_error("frobnicate", "unknown subcommand 'frobnicate' (the subcommands: build, query, info,");
  expect_usage_error("--verison", "unknown flag '--verison'; did you mean '--version'?");
}

TEST(CliCommandLine, AMistypedFlagIsNamedWithTheClosestOneAndUnderscoresAreNotDashes) {
  // The config's spelling of a flag: refused, with the flag's.
  expect_usage_error("build s.pcd -o m.bgk --max_range 8", "build: unknown flag '--max_range'; did you mean '--max-range'?");
  expect_usage_error("build s.pcd -o m.bgk --resoltion=0.2", "build: unknown flag '--resoltion'; did you mean '--resolution'?");
  expect_usage_error("render m.bgk -o m.png --Title x", "render: unknown flag '--Title'; did you mean '--title'?");
  // Named before the missing -o it is likely meant to be.
  expect_usage_error("build s.pcd --ouput m.bgk", "build: unknown flag '--ouput'; did you mean '--output'?");
  expect_usage_error("view m.bgk -o m.html --zzz", "view: unknown flag '--zzz' (see bgkmap view --help)");
  // A negative number is a value, not a flag.
  expect_usage_error("render m.bgk -o m.png --z -1.5 -2.5", "not expected: -2.5");
}

// Every numeric flag of the commands other than build has a range (build's: test_build_param_table).
TEST(CliCommandLine, EvalAndRenderHeightsAndSpacingsOutsideTheirRangesAreUsageErrors) {
  expect_usage_error("render m.bgk -o m.png --z nan", "--z nan is not a finite height");
  expect_usage_error("eval m.bgk --json m.json --slice-z inf", "--slice-z inf is not a finite height");
  expect_usage_error("eval m.bgk --json m.json --spacing -1", "--spacing: Value -1 not in range");
  expect_usage_error("eval m.bgk --json m.json --spacing inf", "--spacing inf is not a finite spacing");
}

TEST(CliCommandLine, ClosestNameAllowsAThirdOfTheLettersWrong) {
  EXPECT_EQ(cli::edit_distance("biuld", "build"), 1u);  // a swap is one edit
  EXPECT_EQ(cli::edit_distance("", "abc"), 3u);
  EXPECT_EQ(cli::edit_distance("kitten", "sitting"), 3u);
  const std::vector<std::string> flags = {"--max-range", "--max-memory", "--method", "-o", "-q"};
  EXPECT_EQ(cli::closest_name("--max_range", flags), "--max-range");
  EXPECT_EQ(cli::closest_name("--max-rnage", flags), "--max-range");
  EXPECT_EQ(cli::closest_name("--metod", flags), "--method");
  EXPECT_EQ(cli::closest_name("--max-mem", flags), "--max-memory");  // the one flag it begins
  EXPECT_EQ(cli::closest_name("--max", flags), "");                  // begins two
  EXPECT_EQ(cli::closest_name("-O", flags), "-o");
  EXPECT_EQ(cli::closest_name("-x", flags), "");  // a one-letter flag is not a typo of another
  EXPECT_EQ(cli::closest_name("--frobnicate", flags), "");
}

// view -o intel.png wrote HTML, render -o x.html a PNG; refused before the map is read (it is
// missing here: an input error would exit 1).
TEST(CliCommandLine, AnOutputNameOfAnotherKindIsRefusedNamingTheFlagAndTheExtensions) {
  expect_usage_error("view missing.bgk -o intel.png", "--output: intel.png: view writes an HTML page; give a name ending in .html or .htm");
  expect_usage_error("render missing.bgk -o x.html", "--output: x.html: render writes a PNG image; give a name ending in .png");
  expect_usage_error("build missing.pcd -o x.txt", "--output: x.txt: unknown map format (extension '.txt'; expected .bgk, .ot, .bt, or an export: .pgm, .ply, .pcd)");
  expect_usage_error("build missing.pcd -o x.bgk -o x", "x: unknown map format (no extension");
  expect_usage_error("merge missing.shards -o x.png", "--output: x.png: unknown map format");
  expect_usage_error("export missing.bgk -o x.ot", "--output: x.ot: export writes a ROS map_server grid or a cloud of occupied cells");
  expect_usage_error("eval missing.bgk --truth t.bt --json j.json --plot roc.svg", "--plot: roc.svg: eval --plot writes a PNG image; give a name ending in .png");
  expect_usage_error("eval missing.bgk --truth t.bt --json j.json --slice s.html", "--slice: s.html: eval --slice writes a PNG image");
  expect_usage_error("station-keeping missing.pcd --cell a:0,0,0 --json j.json --plot p.jpg", "--plot: p.jpg: station-keeping --plot writes a PNG image");
  // The case of the extension does not matter.
  const Result r = run("render missing.bgk -o X.PNG");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("missing.bgk"), std::string::npos) << r.output;
}

TEST(CliCommandLine, BuildHelpGroupsTheMethodsFlagsAndTypesCountsAsIntegers) {
  const Result help = run("build --help");
  ASSERT_EQ(help.status, 0) << help.output;
  for (const char* group : {"Parameters of octomap:", "Parameters of gpom, wgpom:", "Parameters of bhm:"})
    EXPECT_NE(help.output.find(group), std::string::npos) << group << "\n" << help.output;
  // The flags every method takes come first, the method groups after.
  EXPECT_LT(help.output.find("--max-range"), help.output.find("Parameters of"));
  EXPECT_GT(help.output.find("--gp-length FLOAT"), help.output.find("Parameters of gpom, wgpom:"));
  for (const char* count : {"--gp-neighbours INT", "--wgp-terms INT", "--bhm-evidence-scans INT", "--bhm-em-iterations INT",
                            "--bhm-block-side INT"})
    EXPECT_NE(help.output.find(count), std::string::npos) << count;
  EXPECT_EQ(help.output.find("--gp-neighbours FLOAT"), std::string::npos);
  EXPECT_NE(help.output.find("--bhm-spacing FLOAT"), std::string::npos);
}

TEST(CliCommandLine, HelpMethodPrintsOnlyThatMethodsFlags) {
  const Result gpom = run("build --help-method gpom");
  ASSERT_EQ(gpom.status, 0) << gpom.output;
  for (const char* flag : {"--gp-noise", "--gp-length", "--gp-neighbours INT", "--gp-covariance"})
    EXPECT_NE(gpom.output.find(flag), std::string::npos) << flag << "\n" << gpom.output;
  for (const char* flag : {"--bhm-spacing", "--prob-hit", "--wgp-terms", "--resolution", "--output"})
    EXPECT_EQ(gpom.output.find(flag), std::string::npos) << flag << "\n" << gpom.output;
  EXPECT_LT(lines(gpom.output), 40u);
  const Result bhm = run("station-keeping --help-method bhm");
  ASSERT_EQ(bhm.status, 0) << bhm.output;
  EXPECT_NE(bhm.output.find("--bhm-gamma"), std::string::npos) << bhm.output;
  EXPECT_NE(bhm.output.find("--free-resolution"), std::string::npos) << bhm.output;
  EXPECT_EQ(bhm.output.find("--gp-noise"), std::string::npos) << bhm.output;
  const Result bgkl = run("build --help-method bgkl");
  ASSERT_EQ(bgkl.status, 0) << bgkl.output;
  EXPECT_NE(bgkl.output.find("--forget-half-life FLOAT=0"), std::string::npos) << bgkl.output;
  EXPECT_EQ(bgkl.output.find("--free-resolution"), std::string::npos) << bgkl.output;
  expect_usage_error("build --help-method gpomm", "--help-method");
}

TEST_F(CliUsage, ACountFlagRefusesAFractionAsAUsageErrorAndTheConfigNamesFileAndKey) {
  const std::string build =
      "build -q " + path("scans") + " -o " + path("m.ot") + " --method gpom --resolution 0.2 --backend cpu --threads 1 ";
  expect_usage_error(build + "--gp-neighbours 2.5", "--gp-neighbours");
  expect_usage_error(build + "--bhm-em-iterations 1e2", "--bhm-em-iterations");
  EXPECT_FALSE(exists("m.ot"));
  {
    std::ofstream cfg(dir_ / "p.yaml");
    cfg << "gp_neighbours: 2.5\n";
  }
  Result r = run(build + "--config " + path("p.yaml"));
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find(path("p.yaml") + ": gp_neighbours must be a whole number"), std::string::npos) << r.output;
  {
    std::ofstream cfg(dir_ / "p.yaml");
    cfg << "gp_neighbours: 12\n";
  }
  r = run(build + "--config " + path("p.yaml") + " --max-range 2 --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream in(dir_ / "r.json");
  const nlohmann::json params = nlohmann::json::parse(in)["params"];
  EXPECT_TRUE(params["gp_neighbours"].is_number_integer()) << params.dump();
  EXPECT_EQ(params["gp_neighbours"].get<int>(), 12);
  r = run(build + "--gp-neighbours 9 --max-range 2 --report " + path("r.json"));
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream again(dir_ / "r.json");
  EXPECT_EQ(nlohmann::json::parse(again)["params"]["gp_neighbours"].get<int>(), 9);
}

// Cell centres such as (-2 + 0.5) * 0.1 printed as -0.15000000000000002.
TEST_F(CliUsage, InfoPrintsComputedNumbersAsTheirDecimals) {
  EXPECT_EQ(decimal_text((-2 + 0.5) * 0.1), "-0.15");
  EXPECT_EQ(decimal_text(0.1 + 0.2), "0.3");
  EXPECT_EQ(decimal_text(1.0 / 3), "0.333333333333333");
  EXPECT_EQ(decimal_text(-1234.5678), "-1234.5678");
  EXPECT_EQ(decimal_value(0.1 + 0.2), 0.3);
  Result r = run("build -q " + path("scans") + " -o " + path("m.bgk") + " --resolution 0.1 --backend cpu --threads 1");
  ASSERT_EQ(r.status, 0) << r.output;
  r = run("info " + path("m.bgk"));
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("bounds (cell centres)"), std::string::npos) << r.output;
  EXPECT_FALSE(std::regex_search(r.output, std::regex("[0-9]{13}"))) << r.output;
  r = run("info --json " + path("m.bgk"));
  ASSERT_EQ(r.status, 0) << r.output;
  const nlohmann::json summary = nlohmann::json::parse(r.output);
  const nlohmann::json& bounds = summary["evidence_cell_centre_bounds"];
  for (const char* side : {"min", "max"})
    for (const nlohmann::json& v : bounds[side]) {
      // A cell centre at resolution 0.1: k * 0.1 + 0.05 for a whole k.
      const double k = (v.get<double>() - 0.05) / 0.1;
      EXPECT_NEAR(k, std::round(k), 1e-9) << bounds.dump();
      EXPECT_EQ(v.get<double>(), decimal_value(v.get<double>())) << bounds.dump();
    }
}

}  // namespace
}  // namespace bgkmap
