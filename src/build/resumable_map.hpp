// The crash safety of a BGK-L build: resuming continues a stored map and passes over the scans it
// already holds (matched by content: path and SHA-256 per input file, a .graph by node count),
// checkpoints write the map atomically every N scans, and every .bgk the build writes records the
// scans it holds. So a build killed at any moment and run again resuming its checkpoint gives the
// same map, byte for byte, as one that was never interrupted.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "bgkmap/build/build_report.hpp"
#include "bgkmap/build/build_session.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/held_inputs.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"
#include "bgkmap/methods/method.hpp"

namespace bgkmap {

class ResumableMap {
 public:
  // Checks the settings and the checkpoint's path before any work: resuming and checkpoints are
  // for BGK-L; a checkpoint needs a .bgk output or a checkpoint path.
  ResumableMap(ResumeSettings settings, const std::vector<std::string>& outputs, const std::string& method);

  // The BGK-L method: the resumed map (settings.params, or the stored parameters with
  // `params`' thresholds) or a new one of `params`. Tells `source` which scans the resumed map
  // holds, and says so once through `note`. A resume path that does not exist yet is fine when
  // it is the checkpoint: the build then starts from the first scan. `forget_half_life` (scans,
  // 0 = off) must be the resumed map's.
  std::unique_ptr<MappingMethod> make_method(const BuildParams& params, double forget_half_life,
                                             const BackendOptions& backend, ScanSource& source,
                                             const std::function<void(const std::string&)>& note);

  // After each inserted scan (file index and place in it, as ScanSource::last_file/last_scan):
  // records it, and writes a checkpoint when one is due.
  void inserted(const ScanSource& source, size_t file, uint64_t scan);

  // Writes a .bgk output with the scans it holds; false for other formats (the method writes those).
  bool write(const std::string& output);

  // Scans of these inputs the resumed map held.
  uint64_t already_held() const { return already_held_; }

  // resumed_from, checkpoint, checkpoint_every, checkpoints_written, scans_already_held, checkpoint_s.
  void add_to(BuildReport& report) const;

 private:
  ResumeSettings settings_;
  Mapper* mapper_ = nullptr;  // owned by the method make_method returned
  HeldInputs held_;
  uint64_t already_held_ = 0;
  uint64_t inserted_ = 0;
  uint64_t checkpoints_ = 0;
  double checkpoint_s_ = 0;
};

}  // namespace bgkmap
