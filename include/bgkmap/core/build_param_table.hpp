// The general parameters of a build (BuildParams) as one table: each one's schema (ParamSpec: the
// flag's spelling, kind, range, unit and help; its default is BuildParams{}'s) and where BuildParams
// holds it. The flags of every command that builds, the YAML config's keys, the report's "params"
// keys (ParamSpec::keyword()), Python's keywords, --help and BuildParams::validate()'s range checks
// are made from it. Not in it: --pose-sigma (four numbers, parse_pose_sigma), --2d and --frame (flags).
#pragma once

#include <string>
#include <vector>

#include "bgkmap/core/params.hpp"
#include "bgkmap/methods/param_error.hpp"
#include "bgkmap/methods/param_spec.hpp"

namespace bgkmap {

// The names of an enum's values in order (KernelType, BeyondRange, PoseFusion, KittiFrame): the
// choices of its flag (defined beside the enums' names, in params.cpp).
template <class Enum>
std::vector<std::string> value_names();

struct BuildParam {
  ParamSpec spec;
  // kNumber and kWholeNumber: the value as a double (a float field as its shortest decimal, as the
  // report writes it); kChoice: its name.
  double (*number)(const BuildParams&) = nullptr;
  void (*set_number)(BuildParams&, double) = nullptr;
  std::string (*name)(const BuildParams&) = nullptr;
  void (*set_name)(BuildParams&, const std::string&) = nullptr;

  // Sets the value if the range takes it (a name if it is one of the choices); otherwise throws
  // ParamError (rejection(spec)) and leaves `params` as it was.
  void set(BuildParams& params, double value) const;
  void set(BuildParams& params, const std::string& value) const;
};

const std::vector<BuildParam>& build_param_table();
// The entry of a key with dashes or underscores (ell, block-depth, block_depth); null for none.
const BuildParam* find_build_param(const std::string& key);

}  // namespace bgkmap
