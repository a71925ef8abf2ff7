#include "cli/build_options.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iterator>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/core/build_param_table.hpp"
#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/io/errors.hpp"
#include "bgkmap/methods/method_descriptor.hpp"
#include "bgkmap/methods/param_error.hpp"

namespace bgkmap::cli {

namespace {

// --help's heading of the parameters these methods read.
std::string method_group(const std::vector<std::string>& methods) {
  std::string out = "Parameters of ";
  for (size_t i = 0; i < methods.size(); ++i) out += (i ? ", " : "") + methods[i];
  return out;
}

// A parameter's flag, writing into `number` or `name`; a whole number is typed INT and a fraction
// refused. Its help shows the unit and range (ParamSpec::help_text).
CLI::Option* add_schema_flag(CLI::App& cmd, const ParamSpec& spec, double& number, std::string& name) {
  const std::string flag = "--" + spec.key;
  CLI::Option* opt = nullptr;
  number = spec.default_number;
  name = spec.default_choice;
  switch (spec.kind) {
    case ParamKind::kWholeNumber:
      opt = cmd.add_option<double, int>(flag, number, help_text(spec))
                ->default_str(std::to_string(std::lround(number)))
                ->check(CLI::Validator(
                    [](std::string& text) {  // CLI11's own refusal would say only "Could not convert"
                      char* end = nullptr;
                      std::strtol(text.c_str(), &end, 10);
                      return !text.empty() && *end == '\0' ? std::string() : text + " is not a whole number";
                    },
                    ""));
      break;
    case ParamKind::kNumber: opt = cmd.add_option(flag, number, help_text(spec))->capture_default_str(); break;
    case ParamKind::kChoice:
      opt = cmd.add_option(flag, name, help_text(spec))->capture_default_str()->check(CLI::IsMember(spec.choices));
      break;
  }
  return opt;
}

// A method parameter's flag: its help group names the methods that read it.
CLI::Option* add_method_flag(CLI::App& cmd, const ParamSpec& spec, double& number, std::string& name) {
  return add_schema_flag(cmd, spec, number, name)->group(method_group(methods_reading(spec.key)));
}

// Runs `f`; a ParamError it throws names the parameters as the command line spells them (--ds).
template <class F>
auto naming_flags(F&& f) -> decltype(f()) {
  try {
    return f();
  } catch (const ParamError& e) {
    throw std::invalid_argument(e.as_flags());
  }
}

// --help-method: the flags of the parameters `method` reads, as --help shows them.
[[noreturn]] void print_method_flags(const CLI::App& cmd, const std::string& method) {
  std::vector<const CLI::Option*> flags;
  for (const ParamSpec* spec : find_method(method)->params) flags.push_back(cmd.get_option("--" + spec->key));
  const std::string command = "bgkmap " + cmd.get_name();
  if (flags.empty()) {
    std::printf("%s reads no parameters of its own: the flags of %s --help are all it takes\n", method.c_str(),
                command.c_str());
  } else {
    std::printf("The parameters %s reads besides the flags every method takes (%s --help):\n", method.c_str(),
                command.c_str());
    const auto formatter = std::dynamic_pointer_cast<CLI::Formatter>(cmd.get_formatter());
    std::fputs(formatter->make_group(method_group({method}), false, flags).c_str(), stdout);
  }
  throw CLI::Success();
}

// --method's help: every method and its one-line summary.
std::string method_help() {
  const std::vector<const MethodDescriptor*>& methods = method_descriptors();
  std::string out;
  for (size_t i = 0; i < methods.size(); ++i)
    out += (i == 0 ? "" : i + 1 == methods.size() ? " or " : ", ") + methods[i]->name + " (" + methods[i]->summary + ")";
  return out;
}

std::string config_key(std::string flag) {
  for (char& c : flag)
    if (c == '-') c = '_';
  return flag;
}

PointFrame point_frame_from_string(const std::string& name, const std::string& config_file) {
  if (name == "world") return PointFrame::kWorld;
  if (name == "sensor") return PointFrame::kSensor;
  throw InputError(config_file, "'frame' must be world or sensor, not '" + name + "'");
}

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (size_t i = 0; i < names.size(); ++i) out += (i ? ", " : "") + names[i];
  return out;
}

}  // namespace

// A flag per general parameter (build_param_table), in the table's order.
void BuildOptions::add_general_options(CLI::App& cmd) {
  for (const BuildParam& param : build_param_table()) {
    double& number = flag_numbers_.emplace_back();
    std::string& name = flag_choices_.emplace_back();
    CLI::Option* opt = add_schema_flag(cmd, param.spec, number, name);
    overrides_.push_back({opt, param.spec.keyword(), [&param, &number, &name](BuildParams& p) {
                            if (param.spec.kind == ParamKind::kChoice) param.set(p, name);
                            else param.set(p, number);
                          }});
  }
}

void BuildOptions::add_to(CLI::App& cmd, MethodChoice method_choice) {
  method_choice_ = method_choice;
  backend_ = backend_defaults_.backend;

  cmd.add_option("--config", config_file_,
                 method_choice == MethodChoice::kFlag
                     ? "YAML file of parameters (same names as the flags, method included); flags override it"
                     : "YAML file of parameters (same names as the flags); flags override it")
      ->check(CLI::ExistingFile);
  add_general_options(cmd);
  frame_opt_ = cmd.add_option("--frame", frame_,
                              "The frame of the points of PCD, PLY and XYZ files (the other formats say): world (as "
                              "stored, the default) or sensor (each point transformed by its scan's pose: VIEWPOINT, "
                              "--poses line or --origin); needed with rotated --poses lines")
                   ->check(CLI::IsMember({"world", "sensor"}));
  overrides_.push_back({frame_opt_, "apply_viewpoint", [this](BuildParams& p) { p.preprocess.apply_viewpoint = frame_ == "sensor"; }});
  viewpoint_opt_ = cmd.add_flag("--apply-viewpoint", apply_viewpoint_, "Alias of --frame sensor")->excludes(frame_opt_);
  overrides_.push_back({viewpoint_opt_, "apply_viewpoint", [this](BuildParams& p) { p.preprocess.apply_viewpoint = apply_viewpoint_; }});
  CLI::Option* planar = cmd.add_flag("--2d", planar_,
                                     "A planar map (planar lasers): points and origins moved onto the centre plane of "
                                     "the layer of cells holding --plane-z, one layer kept, distances in the plane");
  overrides_.push_back({planar, "planar", [this](BuildParams& p) { p.preprocess.planar = planar_; }});
  cmd.add_option("--poses", poses_file_,
                 "Sensor poses of inputs without one of their own (PLY, XYZ, PCD without a VIEWPOINT or with PCL's "
                 "default), one data line each in input order: time x y z qx qy qz qw (as bgkmap simulate's "
                 "poses.txt), optionally followed by the scan's pose covariance as in --pose-covariance");
  cmd.add_option("--origin", origin_,
                 "Sensor origin X,Y,Z of every input without a pose of its own (PLY, XYZ, PCD without a VIEWPOINT "
                 "or with PCL's default), identity orientation (without --poses)")
      ->expected(3)
      ->delimiter(',');
  cmd.add_option("--topic", topics_,
                 "ROS bag inputs (.bag): a topic to map, sensor_msgs/PointCloud2 or LaserScan, one scan a message "
                 "in bag time order (repeat for more topics)");
  cmd.add_option("--tf-frame", tf_frame_,
                 "ROS bag inputs: pose each message by the bag's /tf and /tf_static, the transform of its "
                 "header.frame_id in this fixed frame (e.g. map, odom) at header.stamp (else --poses: a line a message)");
  CLI::Option* pose_sigma =
      cmd.add_option("--pose-sigma", pose_sigma_,
                     "Pose uncertainty of every scan: XY,YAW or XY,YAW,Z,ROLLPITCH, standard deviations of the "
                     "translation along x and y (m), the yaw (rad), z (m), roll and pitch (rad), at most 1e6 m and pi rad; "
                     "bgkl, bgk, gpom and wgpom then take it by --pose-fusion");
  overrides_.push_back({pose_sigma, "pose_sigma", [this](BuildParams& p) {
                          p.preprocess.pose_sigma = parse_pose_sigma(pose_sigma_, "--pose-sigma");
                        }});
  cmd.add_option("--pose-covariance", pose_covariance_file_,
                 "Pose uncertainty per scan: a poses file (time x y z qx qy qz qw) with a 3x3 (x, y, yaw) or 6x6 "
                 "(x, y, z, roll, pitch, yaw) row-major covariance on each line, one line per scan in input order");
  threads_opt_ = cmd.add_option("--threads", threads_, "Host threads (0 = all cores; at most 8 a core, at least 64); with 8 or more, build reads and prepares the next scan on one of them")->capture_default_str();
  backend_opt_ = cmd.add_option("--backend", backend_,
                                "auto (an OpenCL GPU if one works, else the CPU path, which beats an OpenCL CPU driver on the same CPU), cpu or opencl")
                     ->capture_default_str();
  device_opt_ = cmd.add_option("--device", device_,
                               "OpenCL device: substring of its platform or device name (also BGKMAP_OPENCL_DEVICE)");
  // Process-wide (core/memory_limit.hpp), so it is set as soon as it is parsed.
  cmd.add_option_function<std::string>(
      "--max-memory", [](const std::string& size) { set_memory_limit_bytes(parse_byte_size(size)); },
      "Memory this process may use (512M, 4G, ...): a step that would go beyond it (a map's growth, a "
      "scan's bucketing, a GP block, a ray update) is refused before it starts, naming the flag that would "
      "make it fit. Default: half the physical memory, or 3/4 of the address-space limit (ulimit -v) if lower");
  add_method_options(cmd);
}

// --method (kFlag), a flag per parameter of the registered methods, and --help-method.
void BuildOptions::add_method_options(CLI::App& cmd) {
  if (method_choice_ == MethodChoice::kFlag)
    method_opt_ = cmd.add_option("--method", method_, method_help())
                      ->check(CLI::IsMember(method_names()))
                      ->capture_default_str();
  for (const ParamSpec* spec : method_param_specs()) {
    double& number = flag_numbers_.emplace_back();
    std::string& name = flag_choices_.emplace_back();
    method_flags_.push_back({add_method_flag(cmd, *spec, number, name), spec, &number, &name});
  }
  cmd.add_option_function<std::string>(
         "--help-method", [&cmd](const std::string& method) { print_method_flags(cmd, method); },
         "Print only the flags of the parameters this method reads, and exit")
      ->check(CLI::IsMember(method_names()));
}

namespace {
// A planar map's plane: the centre plane of the layer holding the height asked for.
void snap_plane(BuildParams& params) {
  if (params.preprocess.planar && std::isfinite(params.preprocess.plane_z_m) && params.grid.resolution_m > 0)
    params.set_planar(params.preprocess.plane_z_m);
}
}  // namespace

void BuildOptions::apply_config(const ConfigTargets& targets) const {
  if (config_file_.empty()) return;
  YAML::Node root;
  try {
    root = YAML::LoadFile(config_file_);
  } catch (const YAML::Exception& e) {
    throw InputError(config_file_, "not valid YAML (" + e.msg + ")");
  }
  if (root.IsNull()) return;
  if (!root.IsMap()) throw InputError(config_file_, "expected a mapping of parameter names to values");
  BuildParams parsed = targets.params ? *targets.params : defaults_;
  for (const auto& item : root) {
    // A key such as [a, b] or {a: 1} is valid YAML but no parameter name.
    if (!item.first.IsScalar())
      throw InputError(config_file_, "line " + std::to_string(item.first.Mark().line + 1) +
                                         ": a parameter name must be a plain word, not a list or mapping");
    const std::string key = config_key(item.first.Scalar());
    const YAML::Node& value = item.second;
    try {
      if (key == "threads" || key == "backend" || key == "device") {
        if (!targets.backend) continue;
        if (key == "threads") {
          targets.backend->threads = value.as<int>();
          if (targets.backend->threads < 0) throw InputError(config_file_, "'threads' must be >= 0");
        }
        if (key == "backend") targets.backend->backend = value.as<std::string>();
        if (key == "device") targets.backend->device_filter = value.as<std::string>();
        continue;
      }
      if (key == "method") {
        if (method_choice_ != MethodChoice::kFlag)
          throw InputError(config_file_, "'method' is not used by this command (it chooses the methods itself)");
        const std::string name = value.as<std::string>();
        const std::vector<std::string>& names = method_names();
        if (std::find(names.begin(), names.end(), name) == names.end())
          throw InputError(config_file_, "method '" + name + "' is not one of " + joined(names));
        if (targets.method) *targets.method = name;
        continue;
      }
      if (const ParamSpec* spec = find_method_param(key)) {
        // Checked as the flag is (ParamSpec::refusal), whichever target is given.
        MethodParams unused;
        MethodParams& into = targets.method_params ? *targets.method_params : unused;
        if (spec->kind == ParamKind::kChoice) into.set(spec->key, value.as<std::string>());
        else into.set(spec->key, value.as<double>());
        continue;
      }
      if (const BuildParam* param = find_build_param(key)) {
        if (param->spec.kind == ParamKind::kChoice) param->set(parsed, value.as<std::string>());
        else param->set(parsed, value.as<double>());
        continue;
      }
      if (key == "pose_sigma") {  // "XY,YAW[,Z,ROLLPITCH]", as the flag
        parsed.preprocess.pose_sigma = parse_pose_sigma(value.as<std::string>(), "pose_sigma");
        continue;
      }
      if (key == "frame" || key == "apply_viewpoint") {  // frame: world|sensor; apply_viewpoint: its alias
        const bool sensor = key == "frame" ? point_frame_from_string(value.as<std::string>(), config_file_) == PointFrame::kSensor
                                           : value.as<bool>();
        parsed.preprocess.apply_viewpoint = sensor;
        if (targets.frame) *targets.frame = sensor ? PointFrame::kSensor : PointFrame::kWorld;
        continue;
      }
      if (key != "2d" && key != "planar") throw InputError(config_file_, "unknown parameter '" + key + "'");
      parsed.preprocess.planar = value.as<bool>();
    } catch (const YAML::Exception&) {
      throw InputError(config_file_, "parameter '" + key + "' has a value of the wrong type");
    } catch (const ParamError& e) {  // named by the YAML key, as the file spells it
      const std::string typed = item.first.Scalar();
      throw InputError(config_file_, e.spelled([&](const std::string& k) {
        return param_key(k) == param_key(typed) ? typed : config_key(k);
      }));
    } catch (const std::invalid_argument& e) {
      throw InputError(config_file_, e.what());
    }
  }
  // The file's values are checked here, with the defaults (or the resumed map's values) for the
  // rest, so that a bad one is refused naming the file rather than as if a flag had set it.
  try {
    BuildParams checked = parsed;
    snap_plane(checked);
    checked.validate();
    if (targets.params) *targets.params = parsed;
    if (targets.method_params) targets.method_params->validate();
  } catch (const ParamError& e) {
    throw InputError(config_file_, e.as_keywords());
  } catch (const std::invalid_argument& e) {
    throw InputError(config_file_, e.what());
  }
}

BuildParams BuildOptions::resolve_params() const {
  BuildParams params = defaults_;
  apply_config({&params});
  return naming_flags([&] {
    for (const Override& o : overrides_)
      if (o.option->count() > 0) o.apply(params);
    snap_plane(params);
    params.validate();
    return params;
  });
}

BuildParams BuildOptions::resolve_params_for_resume(const BuildParams& stored) const {
  BuildParams wanted = stored;
  apply_config({&wanted});
  return naming_flags([&] {
    for (const Override& o : overrides_)
      if (o.option->count() > 0) o.apply(wanted);
    snap_plane(wanted);
    return resumed_params(stored, wanted);
  });
}

BackendOptions BuildOptions::resolve_backend() const {
  BackendOptions backend = backend_defaults_;
  apply_config({nullptr, &backend});
  if (threads_opt_->count()) backend.threads = threads_;
  if (backend_opt_->count()) backend.backend = backend_;
  if (device_opt_->count()) backend.device_filter = device_;
  check_thread_count(backend.threads);
  return with_environment(backend);
}

BackendOptions with_environment(BackendOptions backend) {
  const char* device = std::getenv("BGKMAP_OPENCL_DEVICE");
  if (backend.device_filter.empty() && device) backend.device_filter = device;
  if (const char* dir = std::getenv("BGKMAP_KERNEL_DIR"); dir && *dir) backend.kernel_dir = dir;
  return backend;
}

std::string BuildOptions::method() const {
  if (method_opt_ && method_opt_->count() > 0) return method_;
  std::string method = "bgkl";
  apply_config({nullptr, nullptr, &method});
  return method;
}

MethodParams BuildOptions::resolve_method_params() const {
  MethodParams params;
  apply_config({nullptr, nullptr, nullptr, &params});
  return naming_flags([&] {
    for (const MethodFlag& flag : method_flags_)
      if (flag.option->count() > 0) {
        if (flag.spec->kind == ParamKind::kChoice) params.set(flag.spec->key, *flag.name);
        else params.set(flag.spec->key, *flag.number);
      }
    params.validate();
    return params;
  });
}

void BuildOptions::check_method_flags_read_by(const std::vector<std::string>& methods) const {
  for (const MethodFlag& flag : method_flags_) {
    if (flag.option->count() == 0) continue;
    const std::vector<std::string> readers = methods_reading(flag.spec->key);
    if (std::any_of(methods.begin(), methods.end(), [&](const std::string& m) {
          return std::find(readers.begin(), readers.end(), m) != readers.end();
        }))
      continue;
    std::string chosen, list;
    for (const std::string& m : methods) chosen += (chosen.empty() ? "" : ", ") + m;
    for (const std::string& m : readers) list += (list.empty() ? "" : ", ") + m;
    throw std::invalid_argument("--" + flag.spec->key + " is read by " + list + ", not by --method " + chosen +
                                ": it would be ignored");
  }
}

nlohmann::json method_params_json(const MethodParams& params, const std::string& method) {
  nlohmann::json out = nlohmann::json::object();
  const MethodDescriptor* chosen = method.empty() ? nullptr : find_method(method);
  if (!method.empty() && !chosen) return out;
  for (const ParamSpec* spec : method_param_specs()) {
    if (chosen && !chosen->reads(spec->key)) continue;
    const std::string key = spec->keyword();
    switch (spec->kind) {
      case ParamKind::kWholeNumber: out[key] = params.whole(spec->key); break;
      case ParamKind::kNumber: out[key] = params.number(spec->key); break;
      case ParamKind::kChoice: out[key] = params.choice(spec->key); break;
    }
  }
  return out;
}

bool set_method_param(MethodParams& params, const std::string& key, const nlohmann::json& value) {
  const ParamSpec* spec = find_method_param(key);
  if (!spec) return false;
  const std::string flag = "--" + spec->key;
  if (spec->kind != ParamKind::kChoice) {
    if (!value.is_number()) throw std::invalid_argument(flag + ": " + value.dump() + " is not a number");
    params.set(spec->key, value.get<double>());
    return true;
  }
  const std::string name = value.is_string() ? value.get<std::string>() : value.dump();
  if (!spec->accepts(name)) throw std::invalid_argument(flag + ": " + name + " not in {" + joined(spec->choices) + "}");
  params.set(spec->key, name);
  return true;
}

BuildConfig read_build_config(const std::string& file, const BuildParams& base) {
  BuildOptions options;
  options.config_file_ = file;
  BuildConfig config;
  config.params = base;
  options.apply_config({&config.params, &config.backend, nullptr, &config.method_params, &config.frame});
  return config;
}

ScanSourceOptions BuildOptions::resolve_source() const {
  if (!poses_file_.empty() && !origin_.empty()) throw std::invalid_argument("give --poses or --origin, not both");
  ScanSourceOptions options;
  apply_config({nullptr, nullptr, nullptr, nullptr, &options.frame});
  if (frame_opt_->count() > 0) options.frame = frame_ == "sensor" ? PointFrame::kSensor : PointFrame::kWorld;
  if (viewpoint_opt_->count() > 0 && apply_viewpoint_) options.frame = PointFrame::kSensor;
  options.kitti_frame = resolve_params().preprocess.kitti_frame;
  options.poses = poses_file_;
  options.pose_covariance = pose_covariance_file_;
  options.topics = topics_;
  options.tf_frame = tf_frame_;
  if (!origin_.empty())
    options.origin = Vec3f{static_cast<float>(origin_[0]), static_cast<float>(origin_[1]), static_cast<float>(origin_[2])};
  return options;
}

}  // namespace bgkmap::cli
