// The crash safety of `bgkmap build` with BGK-L: --resume continues a stored map and passes over
// the scans it already holds (matched by content: path and SHA-256 per input file, a .graph by
// node count), --checkpoint-every N writes the map atomically every N scans, and every .bgk the
// build writes records the scans it holds. So a build killed at any moment and run again with
// --resume MAP.bgk gives the same map, byte for byte, as one that was never interrupted.
#pragma once

#include <CLI/CLI.hpp>

#include <cstdint>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/held_inputs.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"
#include "cli/build_options.hpp"

namespace bgkmap::cli {

struct ResumeOptions {
  std::string resume;       // --resume MAP.bgk
  std::string checkpoint;   // --checkpoint PATH.bgk; default: the build's first .bgk output
  uint64_t every = 0;       // --checkpoint-every N scans, 0 = none

  void add_to(CLI::App& cmd);
};

class ResumableMap {
 public:
  // Checks the flags and the checkpoint's path before any work: resuming and checkpoints are for
  // --method bgkl; a checkpoint needs a .bgk output or --checkpoint.
  ResumableMap(ResumeOptions options, const std::vector<std::string>& outputs, const std::string& method);

  // The BGK-L method: the resumed map (a parameter that fixes what alpha/beta mean may not
  // change) or a new one. Tells `source` which scans the resumed map holds, and says so once on
  // stderr. A --resume path that does not exist yet is fine when it is the checkpoint: the build
  // then starts from the first scan.
  std::unique_ptr<MappingMethod> make_method(const BuildOptions& options, const BackendOptions& backend,
                                             ScanSource& source);

  // After each inserted scan (file index and place in it, as ScanSource::last_file/last_scan):
  // records it, and writes a checkpoint when one is due.
  void inserted(const ScanSource& source, size_t file, uint64_t scan);

  // Writes a .bgk output with the scans it holds; false for other formats (the method writes those).
  bool write(const std::string& output);

  // Scans of these inputs the resumed map held.
  uint64_t already_held() const { return already_held_; }

  // Report entries: "resumed_from", "checkpoint" {path, every, written}, counts
  // "scans_already_held", timing "checkpoint_s".
  void add_to_report(nlohmann::json& report) const;

 private:
  ResumeOptions options_;
  Mapper* mapper_ = nullptr;  // owned by the method make_method returned
  HeldInputs held_;
  uint64_t already_held_ = 0;
  uint64_t inserted_ = 0;
  uint64_t checkpoints_ = 0;
  double checkpoint_s_ = 0;
};

}  // namespace bgkmap::cli
