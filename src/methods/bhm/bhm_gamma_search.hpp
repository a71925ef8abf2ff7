// The Bayesian Hilbert map's gamma chosen by the evidence (--bhm-gamma 0): the first scans' training
// data are kept, a model per candidate gamma learns them in turn (every k-th point and beam, at most
// kMaxEvidencePoints points a scan, so that the search's memory and time stay bounded whatever the
// scans and the candidates' reach), each update's evidence lower bound (BhmUpdateStats::elbo) is
// summed per candidate, and a model with the candidate of the largest sum learns the kept scans in
// full and goes on. One model at a time. Internal header of the bhm method (tests include it).
#pragma once

#include <memory>
#include <vector>

#include "bgkmap/core/progress.hpp"
#include "methods/bhm/bhm_model.hpp"

namespace bgkmap {

// Points (hits and free samples) of one scan a candidate learns at most; beams are thinned by the
// same stride.
constexpr size_t kMaxEvidencePoints = 20000;

// The candidates: 1.25 / spacing^2 (20 m^-2 at 0.25 m, the default) times 2^(k/2), k in [-6, 6],
// those whose features reach at most a block's side (beyond it the blocks of one colour would
// share points: bhm_model.hpp). Increasing.
std::vector<double> bhm_gamma_candidates(const BhmParams& params);

class BhmGammaSearch {
 public:
  struct Candidate {
    double gamma = 0;
    double elbo = 0;  // summed over the scans so far
  };

  // params: everything but gamma; gram: the engine every candidate's model uses (null: CPU).
  BhmGammaSearch(const BhmParams& params, std::shared_ptr<BlockGramEngine> gram = nullptr);

  // One scan (BhmModel::update's arguments), kept for choose().
  void add_scan(std::vector<Vec3d> points, std::vector<double> labels, std::vector<BhmBeam> beams,
                double beam_density);
  int scans() const { return static_cast<int>(scans_.size()); }
  // Every candidate learns the kept scans (thinned); returns a model (ELBOs off) with the gamma of
  // the largest summed ELBO (the first such) that has learned the kept scans in full, for the scans
  // to come. Once.
  // `settled`: the rows and blocks of the chosen model's updates on the kept scans (the map's counts).
  // `progress` hears of each candidate's model learned, and of the chosen one's.
  BhmModel choose(BhmUpdateStats& settled, const ProgressCallback& progress = {});
  // After choose(): every candidate's summed ELBO, and which one was chosen.
  const std::vector<Candidate>& candidates() const { return candidates_; }
  size_t best() const { return best_; }

 private:
  struct KeptScan {
    std::vector<Vec3d> points;
    std::vector<double> labels;
    std::vector<BhmBeam> beams;
    double beam_density = 0;
  };
  BhmParams params_;
  std::shared_ptr<BlockGramEngine> gram_;
  std::vector<Candidate> candidates_;
  std::vector<KeptScan> scans_;
  size_t best_ = 0;
  bool chosen_ = false;
};

}  // namespace bgkmap
