#include "methods/bhm_gamma_search.hpp"

#include <cmath>
#include <memory>
#include <stdexcept>
#include <utility>

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

BhmGammaSearch::BhmGammaSearch(const BhmParams& params, std::shared_ptr<BlockGramEngine> gram)
    : params_(params), gram_(std::move(gram)) {
  for (double gamma : bhm_gamma_candidates(params)) candidates_.push_back({gamma, 0.0});
}

void BhmGammaSearch::add_scan(std::vector<Vec3d> points, std::vector<double> labels, std::vector<BhmBeam> beams,
                              double beam_density) {
  if (chosen_) throw std::logic_error("BhmGammaSearch::add_scan after choose");
  scans_.push_back({std::move(points), std::move(labels), std::move(beams), beam_density});
}

BhmModel BhmGammaSearch::choose() {
  if (chosen_) throw std::logic_error("BhmGammaSearch::choose twice");
  chosen_ = true;
  std::unique_ptr<BhmModel> best;
  for (size_t c = 0; c < candidates_.size(); ++c) {
    BhmParams p = params_;
    p.gamma = candidates_[c].gamma;
    p.elbo = true;
    BhmModel model(p, gram_);
    for (const KeptScan& scan : scans_)
      candidates_[c].elbo += model.update(scan.points, scan.labels, scan.beams, scan.beam_density).elbo;
    if (!best || candidates_[c].elbo > candidates_[best_].elbo) {
      best_ = c;
      best.reset();  // the older best goes before the next candidate starts
      best = std::make_unique<BhmModel>(std::move(model));
    }
  }
  scans_.clear();
  best->set_elbo(false);
  return std::move(*best);
}

}  // namespace bgkmap
