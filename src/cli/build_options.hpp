// The build's options: map parameters (flags, a YAML config, or a resumed map's header) and the
// back-end choice. Shared by `build` and any command that builds maps.
#pragma once

#include <CLI/CLI.hpp>

#include <nlohmann/json.hpp>

#include <deque>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "bgkmap/build/build_session.hpp"  // resumed_params, check_one_pose_uncertainty
#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap::cli {

// Whether a command builds with one method chosen by --method (build, eval) or chooses the
// methods itself (station-keeping compares several).
enum class MethodChoice { kFlag, kByCommand };

// A YAML config's settings without a command line (Python's build(config=...)): the keys,
// checks and messages of --config; parameters over `base` (the defaults, or a resumed map's).
struct BuildConfig {
  BuildParams params;
  BackendOptions backend;
  MethodParams method_params;
  std::optional<PointFrame> frame;
};
BuildConfig read_build_config(const std::string& file, const BuildParams& base);

class BuildOptions {
 public:
  // Adds --resolution ... --backend, the method parameters, --config and (kFlag) --method to `cmd`.
  void add_to(CLI::App& cmd, MethodChoice method_choice = MethodChoice::kFlag);

  // Defaults, then the YAML config (if any), then the flags given on the command line.
  BuildParams resolve_params() const;
  // The same for a resumed map: its stored parameters, and a flag or config key that would
  // change the map's meaning is refused with a clear error.
  BuildParams resolve_params_for_resume(const BuildParams& stored) const;
  BackendOptions resolve_backend() const;
  // --method, else the config's `method`, else bgkl; the same order for the parameters only some
  // methods read.
  std::string method() const;
  MethodParams resolve_method_params() const;
  // Throws std::invalid_argument naming a method flag given on the command line that none of
  // `methods` reads (it would be ignored: an octomap build asked to forget would not).
  void check_method_flags_read_by(const std::vector<std::string>& methods) const;
  // --poses / --origin: the sensor poses of inputs that have none of their own (PLY, XYZ, PCD
  // without a VIEWPOINT); --frame (or the config's frame) if given; --kitti-frame; --pose-covariance.
  ScanSourceOptions resolve_source() const;
  // --config's file, or empty.
  const std::string& config_file() const { return config_file_; }

 private:
  struct Override {
    CLI::Option* option;
    std::string key;  // params_to_json key
    std::function<void(BuildParams&)> apply;
  };
  void add_general_options(CLI::App& cmd);
  void add_method_options(CLI::App& cmd);
  // A method parameter's flag and the storage it writes (number or name, by its kind).
  struct MethodFlag {
    CLI::Option* option;
    const ParamSpec* spec;
    double* number;
    std::string* name;
  };
  // What the config file sets, key by key, into whichever of these is given (keys of the others
  // are still checked to be known). Throws InputError naming the file and the key.
  struct ConfigTargets {
    BuildParams* params = nullptr;
    BackendOptions* backend = nullptr;
    std::string* method = nullptr;
    MethodParams* method_params = nullptr;
    std::optional<PointFrame>* frame = nullptr;  // set when the file says (frame, apply_viewpoint)
  };
  void apply_config(const ConfigTargets& targets) const;
  friend BuildConfig read_build_config(const std::string& file, const BuildParams& base);

  BuildParams defaults_;
  BackendOptions backend_defaults_;
  // Storage the flags write into.
  std::string frame_;
  bool apply_viewpoint_ = false, planar_ = false;
  std::string poses_file_, pose_covariance_file_, pose_sigma_;
  std::vector<double> origin_;
  std::vector<std::string> topics_;  // ROS bag inputs
  std::string tf_frame_;
  int threads_ = 0;
  std::string backend_, device_;
  std::string config_file_;
  MethodChoice method_choice_ = MethodChoice::kFlag;
  std::string method_ = "bgkl";
  std::deque<double> flag_numbers_;  // storage of the schema's flags, general and methods' (stable addresses)
  std::deque<std::string> flag_choices_;
  std::vector<Override> overrides_;
  std::vector<MethodFlag> method_flags_;
  CLI::Option* method_opt_ = nullptr;
  CLI::Option* frame_opt_ = nullptr;
  CLI::Option* viewpoint_opt_ = nullptr;
  CLI::Option* threads_opt_ = nullptr;
  CLI::Option* backend_opt_ = nullptr;
  CLI::Option* device_opt_ = nullptr;
};

// `backend` with what the environment adds for users: BGKMAP_OPENCL_DEVICE as the device filter
// when none is given, BGKMAP_KERNEL_DIR as the folder of the OpenCL kernels' sources (the command
// line and the Python module read them; the library reads no environment variable).
BackendOptions with_environment(BackendOptions backend);

// The method parameters `method` reads (every one for an empty name) as report JSON keys
// (free_resolution, prob_hit, ...).
nlohmann::json method_params_json(const MethodParams& params, const std::string& method = "");
// Sets the parameter a report key names (free_resolution, prob_hit, ...) to a number or a name;
// false for a key that is none. std::invalid_argument for a name not among its choices or a value
// of the wrong kind; ranges are MethodParams::validate()'s.
bool set_method_param(MethodParams& params, const std::string& key, const nlohmann::json& value);

}  // namespace bgkmap::cli
