// What a build did: its settings, counts, timings, back end and skipped inputs; report_json()
// is the JSON report `bgkmap build --report` writes and bgkmap.build() returns.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "bgkmap/core/params.hpp"
#include "bgkmap/integrate/backend.hpp"
#include "bgkmap/io/map_io.hpp"
#include "bgkmap/io/scan_source.hpp"
#include "bgkmap/mapper.hpp"

namespace bgkmap {

// An input file skip_bad_inputs passed over: its path and the one-line error.
struct SkippedInput {
  std::string path, error;
};

struct BuildReport {
  // Settings.
  std::string method;
  BuildParams params;                 // the map's (a resumed map's own)
  nlohmann::json method_params = nlohmann::json::object();  // the method's own parameters, by report key
  BackendOptions backend_asked;       // threads, backend and device as asked for
  ScanSourceOptions source;
  std::vector<std::string> inputs;    // every scan file, folders expanded
  std::vector<std::string> outputs;
  TreeValues ot_values = TreeValues::kClassified;
  // Counts.
  BuildCounts counts;
  uint64_t blocks_touched = 0, known_cells = 0;
  std::map<std::string, uint64_t> skipped_messages, pose_sources;  // ScanSource's
  std::vector<SkippedInput> skipped;
  // Resuming and checkpoints.
  std::string resumed_from, checkpoint;
  uint64_t checkpoint_every = 0, checkpoints_written = 0, scans_already_held = 0;
  // Timings (s) and memory.
  InsertTiming timing;
  double read_s = 0, write_s = 0, total_s = 0, checkpoint_s = 0;
  double peak_rss_mb = 0;
  BackendInfo backend;
  std::string omp_wait_policy;
};

// The JSON report: params, inputs, outputs, ot_values, counts, timing, backend, peak_rss_mb,
// resumed_from, checkpoint, skipped_inputs.
nlohmann::json report_json(const BuildReport& report);

}  // namespace bgkmap
