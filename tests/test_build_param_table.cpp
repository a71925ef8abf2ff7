// The general parameters' one table (core/build_param_table.hpp): for each one the flag, its --help,
// the YAML key, the report key and the refusal of a value out of range agree, and each front end
// names a refused parameter as its user spells it.
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>

#include "bgkmap/core/build_param_table.hpp"
#include "bgkmap/core/params_io.hpp"
#include "bgkmap/io/errors.hpp"
#include "cli/build_options.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

struct Parsed {
  CLI::App app{"build", "build"};
  cli::BuildOptions options;
  Parsed() { options.add_to(app); }
  void parse(const std::string& args) { app.parse(args, false); }
};

std::string text_of(double v) {
  std::ostringstream text;
  text.precision(17);
  text << v;
  return text.str();
}

// A value in range other than the default, as flag text.
std::string other_value(const ParamSpec& spec) {
  if (spec.kind == ParamKind::kChoice) return spec.choices.back() == spec.default_choice ? spec.choices.front() : spec.choices.back();
  double v = spec.default_number + 1;
  if (!spec.accepts(v)) v = 0.5 * (std::max(spec.lo.value, 0.0) + spec.hi.value);
  EXPECT_TRUE(spec.accepts(v)) << spec.key << " " << v;
  return text_of(v);
}

// The message of what `call` throws as E; "no throw" if it returns.
template <class E, class F>
std::string message(F&& call) {
  try {
    call();
  } catch (const E& e) {
    return e.what();
  }
  return "no throw";
}

TEST(BuildParamTable, EachParameterIsDeclaredOnceWithItsDefaultReportKeyAndHelp) {
  const nlohmann::json report = params_to_json(BuildParams{});
  Parsed build;
  std::set<std::string> keys;
  for (const BuildParam& p : build_param_table()) {
    const ParamSpec& spec = p.spec;
    SCOPED_TRACE(spec.key);
    EXPECT_TRUE(keys.insert(spec.key).second);
    EXPECT_EQ(spec.key.find('_'), std::string::npos);
    EXPECT_EQ(find_build_param(spec.keyword()), &p);
    EXPECT_EQ(find_build_param(spec.key), &p);
    // --help shows the help with the unit and range; a number's range is stated.
    const CLI::Option* flag = build.app.get_option("--" + spec.key);
    EXPECT_EQ(flag->get_description(), help_text(spec));
    if (spec.kind == ParamKind::kChoice) {
      EXPECT_TRUE(spec.accepts(spec.default_choice));
      EXPECT_EQ(p.name(BuildParams{}), spec.default_choice);
      for (const std::string& name : spec.choices) EXPECT_NE(spec.help.find(name), std::string::npos) << name;
    } else {
      EXPECT_TRUE(spec.accepts(spec.default_number));
      EXPECT_EQ(p.number(BuildParams{}), spec.default_number);
      EXPECT_NE(help_text(spec).find(range_text(spec)), std::string::npos);
      if (!spec.unit.empty()) {
        EXPECT_NE(help_text(spec).find(spec.unit), std::string::npos);
      }
    }
    // The report's key is the keyword, holding the default (the keys only some maps carry aside).
    if (report.contains(spec.keyword())) {
      if (spec.kind == ParamKind::kChoice) EXPECT_EQ(report.at(spec.keyword()), spec.default_choice);
      else EXPECT_EQ(report.at(spec.keyword()).get<double>(), spec.default_number);
    } else {
      EXPECT_TRUE(spec.key == "plane-z" || spec.key == "pose-fusion" || spec.key == "kitti-frame");
    }
  }
  // Every key of a report's params is in the table, or one of the few that are not one value.
  for (const auto& item : report.items())
    if (!find_build_param(item.key())) {
      EXPECT_TRUE(item.key() == "apply_viewpoint") << item.key();
    }
}

TEST(BuildParamTable, FlagYamlKeyAndReportAgreeForEveryParameter) {
  const testing::TempDir dir("build-param-table");
  for (const BuildParam& p : build_param_table()) {
    const ParamSpec& spec = p.spec;
    SCOPED_TRACE(spec.key);
    const std::string value = other_value(spec);
    const bool planar = spec.key == "plane-z";  // a 3-D map has no plane
    Parsed by_flag;
    by_flag.parse("--" + spec.key + "=" + value + (planar ? " --2d" : ""));
    const nlohmann::json flagged = params_to_json(by_flag.options.resolve_params());
    for (const std::string& key : {spec.key, spec.keyword()}) {  // YAML takes dashes or underscores
      const std::filesystem::path yaml = dir / "p.yaml";
      std::ofstream(yaml) << key << ": " << value << "\n" << (planar ? "planar: true\n" : "");
      Parsed by_config;
      by_config.parse("--config " + yaml.string());
      EXPECT_EQ(params_to_json(by_config.options.resolve_params()).dump(), flagged.dump());
    }
    ASSERT_TRUE(flagged.contains(spec.keyword()));
    if (spec.kind == ParamKind::kChoice) {
      EXPECT_EQ(flagged.at(spec.keyword()), value);
    } else if (!planar) {
      EXPECT_NEAR(flagged.at(spec.keyword()).get<double>(), std::stod(value), 1e-6 * std::stod(value));
    }
  }
}

TEST(BuildParamTable, AValueOutOfRangeIsRefusedNamingTheFlagOrTheYamlKey) {
  const testing::TempDir dir("build-param-table-range");
  for (const BuildParam& p : build_param_table()) {
    const ParamSpec& spec = p.spec;
    if (spec.kind == ParamKind::kChoice || !std::isfinite(spec.lo.value)) continue;
    SCOPED_TRACE(spec.key);
    for (double bad : {spec.lo.value - 1, std::isfinite(spec.hi.value) ? spec.hi.value + 1 : spec.lo.value - 2}) {
      Parsed by_flag;
      by_flag.parse("--" + spec.key + "=" + text_of(bad));
      const std::string flag_error = message<std::invalid_argument>([&] { by_flag.options.resolve_params(); });
      EXPECT_EQ(flag_error, rejection(spec).as_flags());
      EXPECT_EQ(flag_error.rfind("--" + spec.key + " must be ", 0), 0u) << flag_error;
      const std::filesystem::path yaml = dir / "bad.yaml";
      std::ofstream(yaml) << spec.keyword() << ": " << text_of(bad) << "\n";
      Parsed by_config;
      by_config.parse("--config " + yaml.string());
      EXPECT_EQ(message<InputError>([&] { by_config.options.resolve_params(); }),
                yaml.string() + ": " + rejection(spec).as_keywords());
    }
  }
  // A name not among the choices: a usage error for the flag, the table's refusal for YAML.
  Parsed by_flag;
  EXPECT_THROW(by_flag.parse("--kernel cubic"), CLI::ValidationError);
  const std::filesystem::path yaml = dir / "bad.yaml";
  std::ofstream(yaml) << "beyond_range: keep\n";
  Parsed by_config;
  by_config.parse("--config " + yaml.string());
  EXPECT_EQ(message<InputError>([&] { by_config.options.resolve_params(); }),
            yaml.string() + ": beyond_range must be free or drop, not 'keep'");
  std::ofstream(yaml) << "kernel: '{ell}'\n";  // the user's braces are quoted as they are
  Parsed braces;
  braces.parse("--config " + yaml.string());
  EXPECT_EQ(message<InputError>([&] { braces.options.resolve_params(); }),
            yaml.string() + ": kernel must be sparse or box, not '{ell}'");
}

TEST(BuildParamTable, RangesAndTheRulesBetweenParametersAsEachFrontEndSpellsThem) {
  const auto refusal = [](const std::string& key) { return rejection(find_build_param(key)->spec); };
  EXPECT_EQ(refusal("resolution").as_flags(),
            "--resolution must be in [0.001, 10000] m (32-bit cell keys of coordinates up to 1e+06 m)");
  EXPECT_EQ(refusal("block_depth").as_keywords(), "block_depth must be a whole number in [1, 7]");
  EXPECT_EQ(refusal("ell").as_flags(), "--ell must be > 0 and finite");
  EXPECT_EQ(refusal("max-range").as_keywords(), "max_range must be > 0 and finite, or 0: no limit");
  EXPECT_EQ(std::string(refusal("free-threshold").what()), "free-threshold must be in [0, 1]");
  EXPECT_EQ(help_text(find_build_param("ell")->spec), "Kernel length scale l (m); > 0 and finite");
  // Each value alone: NaN and infinities refused; the ends as the table says; the old ranges kept.
  BuildParams p;
  p.preprocess.plane_z_m = std::nan("");
  EXPECT_EQ(message<ParamError>([&] { p.validate(); }), "plane-z must be finite");
  p = BuildParams{};
  p.grid.resolution_m = 1e-3;  // closed ends
  p.classify.occupied_threshold = 1;
  p.classify.free_threshold = 0;
  p.preprocess.end_margin_m = 0;
  EXPECT_NO_THROW(p.validate());
  p.kernel.ell_m = std::numeric_limits<float>::infinity();
  EXPECT_THROW(p.validate(), ParamError);
  // Between parameters: the message names both, by flag and by YAML key.
  Parsed by_flag;
  by_flag.parse("--ds 1e-30 --resolution 0.1");
  EXPECT_EQ(message<std::invalid_argument>([&] { by_flag.options.resolve_params(); }),
            "--ds 1e-30 m is below 0.01 of --resolution 0.1 m (0 turns the voxel filter off)");
  Parsed thresholds;
  thresholds.parse("--free-threshold 0.8");
  EXPECT_EQ(message<std::invalid_argument>([&] { thresholds.options.resolve_params(); }),
            "--free-threshold must not exceed --occupied-threshold");
  const testing::TempDir dir("build-param-table-rules");
  const std::filesystem::path yaml = dir / "p.yaml";
  std::ofstream(yaml) << "ds: 1e-30\n";
  Parsed by_config;
  by_config.parse("--config " + yaml.string());
  EXPECT_EQ(message<InputError>([&] { by_config.options.resolve_params(); }),
            yaml.string() + ": ds 1e-30 m is below 0.01 of resolution 0.1 m (0 turns the voxel filter off)");
  // A method's parameter too: --prob-hit on the command line, the key as written in a config.
  Parsed method_flag;
  method_flag.parse("--method octomap --prob-hit 0.2");
  EXPECT_EQ(message<std::invalid_argument>([&] { method_flag.options.resolve_method_params(); }),
            "--prob-hit must be in (0.5, 1)");
  for (const std::string key : {"prob-hit", "prob_hit"}) {  // the key as the file spells it
    std::ofstream(yaml) << key << ": 0.2\n";
    Parsed method_config;
    method_config.parse("--config " + yaml.string());
    EXPECT_EQ(message<InputError>([&] { method_config.options.resolve_method_params(); }),
              yaml.string() + ": " + key + " must be in (0.5, 1)");
  }
}

}  // namespace
}  // namespace bgkmap
