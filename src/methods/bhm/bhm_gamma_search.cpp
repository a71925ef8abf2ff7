#include "methods/bhm/bhm_gamma_search.hpp"

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <utility>

#include "bgkmap/core/memory_limit.hpp"
#include "core/progress_counter.hpp"

namespace bgkmap {

std::vector<double> bhm_gamma_candidates(const BhmParams& params) {
  std::vector<double> out;
  const double centre = 1.25 / (params.spacing_m * params.spacing_m);
  for (int k = -6; k <= 6; ++k) {
    BhmParams p = params;
    p.gamma = centre * std::pow(2.0, 0.5 * k);
    if (BhmModel(p).reach_m() <= p.block_side * p.spacing_m) out.push_back(p.gamma);
  }
  if (out.empty())
    throw std::invalid_argument("bhm: no gamma to choose from: every candidate's features reach beyond a block "
                                "(give a larger --bhm-block-side or --bhm-gamma)");
  return out;
}

namespace {
// A smaller gamma reaches farther, so a candidate's update can need far more memory than the
// given gamma's: each is checked before it starts, as the method checks its own updates.
void require_candidate_memory(const BhmModel& model, const std::vector<Vec3d>& points,
                              const std::vector<BhmBeam>& beams, size_t scan) {
  size_t reached = 0;
  const double bytes = model.update_bytes(points, beams, &reached);
  char gamma[32];
  std::snprintf(gamma, sizeof gamma, "%.4g", model.params().gamma);
  require_memory(bytes,
                 std::string("bhm's choice of gamma (gamma ") + gamma + " m^-2 learning kept scan " +
                     std::to_string(scan + 1) + ": " + std::to_string(points.size()) + " training points reaching " +
                     std::to_string(reached) + " blocks)",
                 "give --bhm-gamma, a larger --free-resolution or a shorter --max-range (or raise --max-memory)");
}
}  // namespace

BhmGammaSearch::BhmGammaSearch(const BhmParams& params, std::shared_ptr<BlockGramEngine> gram)
    : params_(params), gram_(std::move(gram)) {
  for (double gamma : bhm_gamma_candidates(params)) candidates_.push_back({gamma, 0.0});
}

void BhmGammaSearch::add_scan(std::vector<Vec3d> points, std::vector<double> labels, std::vector<BhmBeam> beams,
                              double beam_density) {
  if (chosen_) throw std::logic_error("BhmGammaSearch::add_scan after choose");
  scans_.push_back({std::move(points), std::move(labels), std::move(beams), beam_density});
}

BhmModel BhmGammaSearch::choose(BhmUpdateStats& settled, const ProgressCallback& progress) {
  if (chosen_) throw std::logic_error("BhmGammaSearch::choose twice");
  chosen_ = true;
  // Every stride-th point and beam of each scan (a scan small enough is used as it is, not copied).
  std::vector<KeptScan> thinned_copies;
  thinned_copies.reserve(scans_.size());
  std::vector<const KeptScan*> thinned;
  for (const KeptScan& scan : scans_) {
    const size_t stride = (scan.points.size() + kMaxEvidencePoints - 1) / kMaxEvidencePoints;
    if (stride <= 1) {
      thinned.push_back(&scan);
      continue;
    }
    KeptScan& t = thinned_copies.emplace_back();
    t.beam_density = scan.beam_density;
    for (size_t i = 0; i < scan.points.size(); i += stride) {
      t.points.push_back(scan.points[i]);
      t.labels.push_back(scan.labels[i]);
    }
    for (size_t i = 0; i < scan.beams.size(); i += stride) t.beams.push_back(scan.beams[i]);
    thinned.push_back(&t);
  }
  ProgressCounter counter(progress, "bhm evidence search", "models", candidates_.size() + 1);
  for (size_t c = 0; c < candidates_.size(); ++c) {
    BhmParams p = params_;
    p.gamma = candidates_[c].gamma;
    p.elbo = true;
    BhmModel model(p, gram_);
    for (size_t i = 0; i < thinned.size(); ++i) {
      const KeptScan& scan = *thinned[i];
      require_candidate_memory(model, scan.points, scan.beams, i);
      candidates_[c].elbo += model.update(scan.points, scan.labels, scan.beams, scan.beam_density).elbo;
    }
    if (candidates_[c].elbo > candidates_[best_].elbo) best_ = c;
    counter.add();
  }
  BhmParams p = params_;
  p.gamma = candidates_[best_].gamma;
  BhmModel model(p, gram_);
  settled = {};
  for (size_t i = 0; i < scans_.size(); ++i) {
    require_candidate_memory(model, scans_[i].points, scans_[i].beams, i);
    const BhmUpdateStats stats = model.update(scans_[i].points, scans_[i].labels, scans_[i].beams, scans_[i].beam_density);
    settled.rows += stats.rows;
    settled.blocks += stats.blocks;
  }
  scans_.clear();
  counter.finish();
  return model;
}

}  // namespace bgkmap
