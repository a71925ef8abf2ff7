// A whole build as one library call: scans in (files or folders of any format ScanSource reads),
// one method, maps and a JSON report out. The CLI's `bgkmap build`, Python's bgkmap.build() and
// the distributed build take their settings in these structs.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "bgkmap/build/build_report.hpp"
#include "bgkmap/core/params.hpp"
#include "bgkmap/core/progress.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap {

// What every build takes, in one process or on MPI ranks: its scans, what it writes, the map's
// parameters and the back end.
struct BuildTargets {
  std::vector<std::string> inputs;   // scan files or folders, mapped in this order
  std::vector<std::string> outputs;  // maps, format from the extension; all renamed together at the end
  std::string report;                // the JSON report's path; empty: none written
  TreeValues ot_values = TreeValues::kClassified;  // what a .ot output holds
  BuildParams params;
  BackendOptions backend;
};

// Continuing a stored BGK-L map, and checkpoints of the map being built.
struct ResumeSettings {
  std::string resume;      // a .bgk map to continue: the scans of these inputs it holds are passed over
  std::string checkpoint;  // where checkpoints go; empty: the first .bgk output
  uint64_t every = 0;      // scans between checkpoints; 0: none
  // The resumed map's parameters from its stored ones; empty: the stored ones with the request's
  // thresholds (params.classify). resumed_params() refuses a change to what alpha/beta mean.
  std::function<BuildParams(const BuildParams& stored)> params;
};

// The stored parameters with `wanted`'s thresholds; std::invalid_argument ("cannot change 'ell'
// when resuming a map ...") when `wanted` differs from `stored` in anything else.
BuildParams resumed_params(const BuildParams& stored, const BuildParams& wanted);

// Refuses covariances per scan (--pose-covariance, --poses lines with one) beside a constant pose
// uncertainty (--pose-sigma, or a resumed map's pose_sigma): the scans' own would take its place
// while the map still recorded it (and applied it to the scans a later --resume adds).
void check_one_pose_uncertainty(const PreprocessParams& params, const ScanSource& source);

struct BuildRequest : BuildTargets {
  ScanSourceOptions source;
  ResumeSettings resume;
  bool skip_bad_inputs = false;  // a scan file that cannot be read is noted and passed over
  std::string method = "bgkl";   // one of method_names()
  MethodParams method_params;
  // The report's entries of the method parameters `method` reads (key -> value); empty: none.
  std::function<nlohmann::json(const MethodParams&, const std::string& method)> method_params_json;
  // Files besides the scans the build reads (a config file): no output may be one of them.
  std::vector<NamedPath> other_inputs;
  ProgressCallback progress;  // the scans read ("build"), then a method's own long phases
  // One line for the user each (a back end that fell back, a skipped input, what a resumed map
  // holds); the library prints nothing.
  std::function<void(const std::string&)> note;
  std::string omp_wait_policy = "runtime default";  // how this process's OpenMP threads wait, for the report
  bool count_known_cells = true;  // the report's known_cells: a pass over every cell of the map
};

class BuildSession {
 public:
  explicit BuildSession(BuildRequest request) : request_(std::move(request)) {}

  // Checks every output and input before any work, maps every scan, writes the outputs and the
  // report (all renamed together once complete: a failure leaves every old file as it was).
  // Throws InputError naming a bad file, std::invalid_argument for settings that do not go
  // together; with skip_bad_inputs, std::runtime_error when no input could be read.
  BuildReport run();

 private:
  BuildRequest request_;
};

}  // namespace bgkmap
