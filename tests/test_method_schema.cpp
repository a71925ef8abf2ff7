// The method descriptors and their parameter schema: what the registry lists is what make_method
// makes, every value is checked by its schema, and the flags and --help of `bgkmap build`, the
// YAML keys, and the report's method_params all come from the same schema.
#include <gtest/gtest.h>

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "bgkmap/methods/param_error.hpp"
#include "cli/build_options.hpp"
#include "support/test_support.hpp"

namespace bgkmap {
namespace {

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}

// A value in range other than the default, as flag text.
std::string other_value(const ParamSpec& spec) {
  if (spec.kind == ParamKind::kChoice) return spec.choices.back() == spec.default_choice ? spec.choices.front() : spec.choices.back();
  double v = spec.default_number + 1;
  if (std::isfinite(spec.hi.value) && !spec.accepts(v)) v = 0.5 * (std::max(spec.lo.value, 0.0) + spec.hi.value);
  if (spec.kind == ParamKind::kWholeNumber) v = std::floor(v);
  EXPECT_TRUE(spec.accepts(v)) << spec.key << " " << v;
  std::ostringstream text;
  text.precision(17);
  text << v;
  return text.str();
}

// A number out of range: below the lowest taken, or above the highest.
double out_of_range(const ParamSpec& spec) {
  const bool zero_taken = !spec.zero_means.empty() && spec.lo.value - 1 == 0;
  if (std::isfinite(spec.lo.value) && !zero_taken) return spec.lo.value - 1;
  return spec.hi.value + 1;
}

TEST(MethodRegistry, NamesComeFromTheDescriptorsAndEachFactoryMakesItsMethod) {
  std::vector<std::string> names;
  for (const MethodDescriptor* d : method_descriptors()) names.push_back(d->name);
  EXPECT_EQ(names, method_names());
  EXPECT_EQ(std::set<std::string>(names.begin(), names.end()).size(), names.size());
  for (const char* name : {"bgkl", "bgk", "counting", "octomap", "gpoctomap", "gpom", "bhm", "wgpom"})
    EXPECT_NE(find_method(name), nullptr) << name;
  BuildParams params;
  params.grid.resolution_m = 0.1;
  for (const MethodDescriptor* d : method_descriptors()) {
    SCOPED_TRACE(d->name);
    EXPECT_FALSE(d->summary.empty());
    EXPECT_FALSE(d->variance.empty());
    EXPECT_EQ(find_method(d->name), d);
    const std::unique_ptr<MappingMethod> method = make_method(d->name, params, MethodParams{}, testing::cpu_backend());
    EXPECT_EQ(method->name(), d->name);
    // The capabilities say what the method does.
    EXPECT_EQ(method->uses_pose_uncertainty(), d->capabilities.pose_uncertainty);
    bool writes_bgk = true;
    try {
      method->check_output("m.bgk");
    } catch (const std::exception&) {
      writes_bgk = false;
    }
    EXPECT_EQ(writes_bgk, d->capabilities.writes_bgk);
    EXPECT_NE(std::find(d->capabilities.devices.begin(), d->capabilities.devices.end(), "cpu"),
              d->capabilities.devices.end());
  }
  EXPECT_EQ(find_method("nonsense"), nullptr);
  EXPECT_THROW(make_method("nonsense", params, MethodParams{}, testing::cpu_backend()), std::invalid_argument);
}

TEST(MethodSchema, EveryParameterIsDeclaredOnceAndItsDefaultIsTaken) {
  std::set<std::string> keys;
  for (const ParamSpec* spec : method_param_specs()) {
    SCOPED_TRACE(spec->key);
    EXPECT_TRUE(keys.insert(spec->key).second);
    EXPECT_EQ(spec->key.find('_'), std::string::npos);
    EXPECT_FALSE(spec->help.empty());
    EXPECT_FALSE(methods_reading(spec->key).empty());
    if (spec->kind == ParamKind::kChoice) EXPECT_TRUE(spec->accepts(spec->default_choice));
    else EXPECT_TRUE(spec->accepts(spec->default_number));
    EXPECT_EQ(find_method_param(spec->keyword()), spec);
  }
  // A shared parameter is one object, read by each method that lists it.
  EXPECT_EQ(methods_reading("free-resolution"), (std::vector<std::string>{"bgk", "gpoctomap", "bhm"}));
  EXPECT_EQ(methods_reading("gp_noise"), (std::vector<std::string>{"gpoctomap", "gpom", "wgpom"}));
  EXPECT_EQ(methods_reading("wgp-terms"), (std::vector<std::string>{"wgpom"}));
  EXPECT_EQ(methods_reading("forget-half-life"), (std::vector<std::string>{"bgkl", "bgk", "counting"}));
  EXPECT_EQ(find_method("bgkl")->params, (std::vector<const ParamSpec*>{find_method_param("forget-half-life")}));
  EXPECT_EQ(find_method_param("gp-nois"), nullptr);
}

// A choice's presets name registered parameters of one method and values their ranges take.
TEST(MethodSchema, EveryPresetValueIsTakenByItsParameter) {
  size_t presets = 0;
  for (const ParamSpec* spec : method_param_specs())
    for (const auto& [name, values] : spec->presets) {
      EXPECT_TRUE(spec->accepts(name)) << spec->key << ": " << name;
      for (const PresetValue& v : values) {
        const ParamSpec* target = find_method_param(v.key);
        ASSERT_NE(target, nullptr) << spec->key << " presets " << v.key;
        if (target->kind == ParamKind::kChoice) {
          EXPECT_TRUE(target->accepts(v.name)) << v.key << " " << v.name;
        } else {
          EXPECT_TRUE(target->accepts(v.number)) << v.key << " " << v.number;
        }
        for (const MethodDescriptor* method : method_descriptors())
          if (method->reads(spec->key)) {
            EXPECT_TRUE(method->reads(v.key)) << method->name << " " << v.key;
          }
        ++presets;
      }
    }
  EXPECT_GE(presets, 3u);  // bhm-mode paper's
}

TEST(MethodSchema, RefusalsAreMadeFromTheRange) {
  const auto refusal = [](const std::string& key) { return find_method_param(key)->refusal(); };
  EXPECT_EQ(refusal("gp-noise"), "gp-noise must be in (0, 1000] (a standard deviation of labels +-1)");
  EXPECT_EQ(refusal("gp-range-sigma"), "gp-range-sigma must be in [0, 100] m");
  EXPECT_EQ(refusal("forget-half-life"), "forget-half-life must be in (0, 1e+09] scans, or 0: off");
  EXPECT_EQ(refusal("gp-bearing-sigma"), "gp-bearing-sigma must be in [0, 0.5) rad");
  EXPECT_EQ(refusal("free-resolution"), "free-resolution must be > 0 and finite");
  EXPECT_EQ(refusal("bhm-support-var"), "bhm-support-var must be >= 0 and finite");
  EXPECT_EQ(refusal("bhm-gamma"), "bhm-gamma must be > 0 and finite, or 0: chosen by the evidence");
  EXPECT_EQ(refusal("gp-neighbours"), "gp-neighbours must be a whole number in [1, 1000], or 0: the mode's count");
  EXPECT_EQ(refusal("bhm-prior-var"), "bhm-prior-var must be in [1e-06, 1e+06]");
  EXPECT_EQ(find_method_param("gp-covariance")->refusal("x"), "gp-covariance must be matern, sparse, se or nn, not 'x'");
  EXPECT_EQ(find_method_param("bhm-free")->refusal("x"), "bhm-free must be points or beams, not 'x'");
  // The ends: open ends and infinities refused, closed ends taken, 0 where it means something.
  const ParamSpec& noise = *find_method_param("gp-noise");
  EXPECT_FALSE(noise.accepts(0.0));
  EXPECT_TRUE(noise.accepts(1000.0));
  EXPECT_FALSE(noise.accepts(std::nextafter(1000.0, 2000.0)));
  EXPECT_FALSE(noise.accepts(std::nan("")));
  EXPECT_FALSE(find_method_param("gp-length")->accepts(INFINITY));
  EXPECT_TRUE(find_method_param("bhm-gamma")->accepts(0.0));
  EXPECT_FALSE(find_method_param("bhm-gamma")->accepts(-1.0));
  EXPECT_FALSE(find_method_param("gp-neighbours")->accepts(2.5));
  EXPECT_TRUE(find_method_param("gp-neighbours")->accepts(1000.0));
  EXPECT_FALSE(find_method_param("gp-neighbours")->accepts(1001.0));
}

TEST(MethodParamsStore, SetChecksKindAndRangeAndGettersAreTyped) {
  MethodParams m;
  EXPECT_DOUBLE_EQ(m.number("prob-hit"), 0.7);
  EXPECT_EQ(m.whole("gp-neighbours"), 0);  // the mode's: 30, or 15 under --gp-mode paper
  EXPECT_EQ(m.choice("gp-covariance"), "matern");
  m.set("gp_noise", 0.25);  // underscores as YAML spells them
  EXPECT_DOUBLE_EQ(m.number("gp-noise"), 0.25);
  m.set("gp-covariance", "se");
  m.set("gp-neighbours", 12);  // an int, as a count is written
  EXPECT_EQ(m.whole("gp-neighbours"), 12);
  EXPECT_EQ(m.choice("gp_covariance"), "se");
  const auto message = [&](auto&& call) {
    try {
      call();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no throw");
  };
  EXPECT_EQ(message([&] { m.set("gp-noise", -1.0); }), "gp-noise must be in (0, 1000] (a standard deviation of labels +-1)");
  EXPECT_DOUBLE_EQ(m.number("gp-noise"), 0.25);  // a refused value leaves the old one
  EXPECT_EQ(message([&] { m.set("gp-neighbours", 2.5); }), "gp-neighbours must be a whole number in [1, 1000], or 0: the mode's count");
  EXPECT_EQ(message([&] { m.set("gp-covariance", "cubic"); }), "gp-covariance must be matern, sparse, se or nn, not 'cubic'");
  EXPECT_EQ(message([&] { m.set("gp-covariance", 1.0); }), "gp-covariance takes a name, not a number");
  EXPECT_EQ(message([&] { m.set("gp-noise", "high"); }), "gp-noise takes a number, not a name");
  EXPECT_EQ(message([&] { m.set("gp-nois", 1.0); }), "unknown method parameter 'gp-nois'");
  EXPECT_EQ(message([&] { (void)m.whole("gp-noise"); }), "gp-noise is not a whole number parameter");
  // The rules between parameters stay each method's own check.
  m.set("clamp-min", 0.9);
  m.set("clamp-max", 0.5);
  EXPECT_EQ(message([&] { m.validate(); }), "clamp-min and clamp-max must satisfy 0 < clamp-min < clamp-max < 1");
  MethodParams supports;
  supports.set("bhm-support-var", 0.1);
  supports.set("bhm-support-side", 0.2);
  EXPECT_NE(message([&] { supports.validate(); }).find("exclude each other"), std::string::npos);
}

// `bgkmap build`'s options, parsed in this process.
struct Parsed {
  CLI::App app{"build", "build"};
  cli::BuildOptions options;
  Parsed() { options.add_to(app); }
  void parse(const std::string& args) { app.parse(args, false); }
};

TEST(MethodSchema, HelpGroupsTheFlagsOfEveryParameterUnderTheMethodsThatReadIt) {
  Parsed build;
  const std::string help = build.app.help();
  // The flags inside the "Parameters of ..." groups, by group.
  std::set<std::string> flags;
  std::string group;
  std::istringstream lines(help);
  for (std::string line; std::getline(lines, line);) {
    if (!line.empty() && line[0] != ' ') group = line;
    if (group.rfind("Parameters of ", 0) != 0) continue;
    const size_t dashes = line.find("--");
    if (dashes == std::string::npos || line.find_first_not_of(' ') != dashes) continue;
    const std::string flag = line.substr(dashes + 2, line.find(' ', dashes) - dashes - 2);
    flags.insert(flag);
    EXPECT_EQ(group, "Parameters of " + joined(methods_reading(flag)) + ":") << flag;
  }
  std::set<std::string> keys;
  for (const ParamSpec* spec : method_param_specs()) keys.insert(spec->key);
  EXPECT_EQ(flags, keys);
  for (const MethodDescriptor* d : method_descriptors())
    EXPECT_NE(help.find(d->name + " (" + d->summary + ")"), std::string::npos) << d->name;
}

TEST(MethodSchema, FlagYamlKeyAndReportAgreeForEveryParameterOfEveryMethod) {
  const testing::TempDir dir("method-schema");
  for (const ParamSpec* spec : method_param_specs()) {
    SCOPED_TRACE(spec->key);
    const std::string value = other_value(*spec);
    Parsed by_flag;
    by_flag.parse("--" + spec->key + "=" + value);
    const MethodParams flagged = by_flag.options.resolve_method_params();
    for (const std::string& key : {spec->key, spec->keyword()}) {  // YAML takes dashes or underscores
      const std::filesystem::path yaml = dir / "p.yaml";
      std::ofstream(yaml) << key << ": " << value << "\n";
      Parsed by_config;
      by_config.parse("--config " + yaml.string());
      const MethodParams configured = by_config.options.resolve_method_params();
      EXPECT_EQ(cli::method_params_json(configured).dump(), cli::method_params_json(flagged).dump());
    }
    EXPECT_NE(cli::method_params_json(flagged).dump(), cli::method_params_json(MethodParams{}).dump());
  }
  // The report holds exactly the parameters each method reads, by their keywords.
  for (const MethodDescriptor* d : method_descriptors()) {
    std::set<std::string> report, schema;
    const nlohmann::json json = cli::method_params_json(MethodParams{}, d->name);
    for (const auto& item : json.items()) report.insert(item.key());
    for (const ParamSpec* spec : d->params) schema.insert(spec->keyword());
    EXPECT_EQ(report, schema) << d->name;
  }
  const nlohmann::json gpom = cli::method_params_json(MethodParams{}, "gpom");
  EXPECT_TRUE(gpom.at("gp_neighbours").is_number_integer());
  EXPECT_EQ(gpom.at("gp_neighbours").get<int>(), 0);
  EXPECT_EQ(gpom.at("gp_covariance").get<std::string>(), "matern");
}

TEST(MethodSchema, AValueOutOfRangeIsRefusedTheSameWayByFlagAndByYaml) {
  const testing::TempDir dir("method-schema-range");
  for (const ParamSpec* spec : method_param_specs()) {
    if (spec->kind == ParamKind::kChoice) continue;
    SCOPED_TRACE(spec->key);
    std::ostringstream bad;
    bad << out_of_range(*spec);
    Parsed by_flag;
    by_flag.parse("--" + spec->key + "=" + bad.str());
    std::string flag_error = "no throw", yaml_error = "no throw";
    try {
      by_flag.options.resolve_method_params();
    } catch (const std::invalid_argument& e) {
      flag_error = e.what();
    }
    EXPECT_EQ(flag_error, rejection(*spec).as_flags());  // --gp-noise must be ...
    const std::filesystem::path yaml = dir / "bad.yaml";
    std::ofstream(yaml) << spec->keyword() << ": " << bad.str() << "\n";
    Parsed by_config;
    by_config.parse("--config " + yaml.string());
    try {
      by_config.options.resolve_method_params();
    } catch (const InputError& e) {
      yaml_error = e.what();
    }
    EXPECT_EQ(yaml_error, yaml.string() + ": " + rejection(*spec).as_keywords());  // gp_noise must be ...
  }
  // A name not among the choices: a usage error for the flag, the schema's refusal for YAML.
  Parsed by_flag;
  EXPECT_THROW(by_flag.parse("--gp-covariance cubic"), CLI::ValidationError);
  const std::filesystem::path yaml = dir / "bad.yaml";
  std::ofstream(yaml) << "gp_covariance: cubic\n";
  Parsed by_config;
  by_config.parse("--config " + yaml.string());
  try {
    by_config.options.resolve_method_params();
    ADD_FAILURE() << "taken";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), yaml.string() + ": gp_covariance must be matern, sparse, se or nn, not 'cubic'");  // the YAML key
  }
}

}  // namespace
}  // namespace bgkmap
