#include "bgkmap/build/build_report.hpp"

#include "bgkmap/core/params_io.hpp"

namespace bgkmap {

namespace {

// The parameters, the method's own, the back end asked for and where poses came from when not
// from the scans themselves.
nlohmann::json params_json(const BuildReport& r) {
  nlohmann::json params = params_to_json(r.params);
  params["method"] = r.method;
  params.update(r.method_params);
  params["threads"] = r.backend_asked.threads;
  params["backend"] = r.backend_asked.backend;
  params["device"] = r.backend_asked.device_filter;
  const ScanSourceOptions& s = r.source;
  if (!s.poses.empty()) params["poses"] = s.poses.string();
  if (s.origin) params["origin"] = {s.origin->x, s.origin->y, s.origin->z};
  if (!s.pose_covariance.empty()) params["pose_covariance"] = s.pose_covariance.string();
  if (!s.topics.empty()) params["topics"] = s.topics;
  if (!s.tf_frame.empty()) params["tf_frame"] = s.tf_frame;
  return params;
}

nlohmann::json counts_json(const BuildReport& r) {
  const BuildCounts& c = r.counts;
  const PreprocessCounts& p = c.preprocess;
  return {{"scans", c.scans},
          {"points_read", p.points_read},
          {"dropped_nonfinite", p.dropped_nonfinite},
          {"dropped_out_of_key_range", p.dropped_out_of_key_range},
          {"dropped_beyond_reach", p.dropped_beyond_reach},
          {"removed_by_downsampling", p.removed_by_downsampling},
          {"beyond_max_range", p.beyond_max_range},
          {"no_returns", p.no_returns},
          {"no_returns_dropped", p.no_returns_dropped},
          {"skipped_messages", r.skipped_messages},
          {"pose_sources", r.pose_sources},
          {"hits", p.hits},
          {"beams", p.beams},
          {"beams_shorter_than_margin", p.beams_shorter_than_margin},
          {"blocks_touched", r.blocks_touched},
          {"block_visits", c.block_visits},
          {"cells_with_evidence", r.known_cells},
          {"pairs_evaluated", c.integrate.pairs_evaluated},
          {"pairs_within_l", c.integrate.pairs_within_support},
          {"share_within_l", c.integrate.pairs_evaluated ? double(c.integrate.pairs_within_support) /
                                                               double(c.integrate.pairs_evaluated)
                                                         : 0.0},
          {"scans_already_held", r.scans_already_held},
          {"inputs_skipped", r.skipped.size()}};
}

nlohmann::json timing_json(const BuildReport& r) {
  const InsertTiming& t = r.timing;
  const uint64_t pairs = r.counts.integrate.pairs_evaluated;
  return {{"read_s", r.read_s},
          {"insert_s", t.insert_s},
          {"preprocess_s", t.preprocess_s},
          {"bucket_s", t.bucket_s},
          {"compute_s", t.compute_s},
          {"device_kernel_s", r.counts.integrate.device_kernel_s},
          {"update_s", t.update_s},
          {"write_s", r.write_s},
          {"total_s", r.total_s},
          {"checkpoint_s", r.checkpoint_s},
          {"pairs_per_s", t.compute_s > 0 ? double(pairs) / t.compute_s : 0.0},
          {"per_scan", t.per_scan_insert_s}};
}

}  // namespace

nlohmann::json report_json(const BuildReport& r) {
  nlohmann::json skipped = nlohmann::json::array();
  for (const SkippedInput& s : r.skipped) skipped.push_back({{"path", s.path}, {"error", s.error}});
  return {
      {"params", params_json(r)},
      {"inputs", r.inputs},
      {"outputs", r.outputs},
      {"ot_values", to_string(r.ot_values)},
      {"counts", counts_json(r)},
      {"timing", timing_json(r)},
      {"backend",
       {{"name", r.backend.name},
        {"device", r.backend.device},
        {"threads", r.backend.threads},
        {"note", r.backend.note},
        {"reason", r.backend.reason},
        {"omp_wait_policy", r.omp_wait_policy}}},
      {"peak_rss_mb", r.peak_rss_mb},
      {"resumed_from", r.resumed_from},
      {"checkpoint", {{"path", r.checkpoint}, {"every", r.checkpoint_every}, {"written", r.checkpoints_written}}},
      {"skipped_inputs", skipped},
  };
}

}  // namespace bgkmap
