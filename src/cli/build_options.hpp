// The build's options: map parameters (flags, a YAML config, or a resumed map's header) and the
// back-end choice. Shared by `build` and any command that builds maps.
#pragma once

#include <CLI/CLI.hpp>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap::cli {

class BuildOptions {
 public:
  // Adds --resolution ... --backend and --config to `cmd`.
  void add_to(CLI::App& cmd);

  // Defaults, then the YAML config (if any), then the flags given on the command line.
  BuildParams resolve_params() const;
  // The same for a resumed map: its stored parameters, and a flag or config key that would
  // change the map's meaning is refused with a clear error.
  BuildParams resolve_params_for_resume(const BuildParams& stored) const;
  BackendOptions resolve_backend() const;
  // --method (bgkl unless given) and the parameters only some methods read.
  const std::string& method() const { return method_; }
  MethodParams resolve_method_params() const;

 private:
  struct Override {
    CLI::Option* option;
    std::string key;  // params_to_json key
    std::function<void(BuildParams&)> apply;
  };
  template <typename T>
  void add_param(CLI::App& cmd, const std::string& flag, T& value, const std::string& help,
                 std::function<void(BuildParams&, const T&)> set);
  void apply_config(BuildParams& params, BackendOptions* backend) const;

  BuildParams defaults_;
  BackendOptions backend_defaults_;
  // Storage the flags write into.
  double resolution_ = 0, ds_ = 0, max_range_ = 0, end_margin_ = 0;
  int block_depth_ = 0;
  float ell_ = 0, sigma0_ = 0, prior_alpha_ = 0, prior_beta_ = 0, occupied_ = 0, free_ = 0, var_ = 0;
  std::string kernel_;
  bool apply_viewpoint_ = false;
  int threads_ = 0;
  std::string backend_, device_;
  std::string config_file_;
  std::string method_ = "bgkl";
  MethodParams method_params_;
  std::vector<Override> overrides_;
  CLI::Option* threads_opt_ = nullptr;
  CLI::Option* backend_opt_ = nullptr;
  CLI::Option* device_opt_ = nullptr;
};

}  // namespace bgkmap::cli
