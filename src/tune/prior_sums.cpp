#include "bgkmap/tune/prior_sums.hpp"

#include "bgkmap/eval/scored_map.hpp"

namespace bgkmap::tune {

namespace {

std::vector<KernelSums> sums_of(const std::vector<Vec3d>& points, const PosteriorAt& posterior, double sigma0,
                                double alpha0, double beta0) {
  std::vector<KernelSums> out;
  out.reserve(points.size());
  for (const Vec3d& p : points) {
    const CellPosterior c = posterior(p.x, p.y, p.z);
    out.push_back({(c.alpha - alpha0) / sigma0, (c.beta - beta0) / sigma0, c.has_evidence});
  }
  return out;
}

std::vector<double> means(const std::vector<KernelSums>& sums, double sigma0, double alpha0, double beta0) {
  std::vector<double> out;
  out.reserve(sums.size());
  for (const KernelSums& s : sums) {
    const double alpha = alpha0 + sigma0 * s.hits, beta = beta0 + sigma0 * s.free;
    out.push_back(s.evidence ? alpha / (alpha + beta) : eval::kUnknownScore);
  }
  return out;
}

}  // namespace

HeldOutSums held_out_sums(const eval::LabelledPoints& points, const PosteriorAt& posterior, double sigma0,
                          double alpha0, double beta0) {
  return {sums_of(points.occupied, posterior, sigma0, alpha0, beta0),
          sums_of(points.free, posterior, sigma0, alpha0, beta0)};
}

eval::LabelledScores scores_from_sums(const HeldOutSums& sums, double sigma0, double alpha0, double beta0) {
  return {means(sums.occupied, sigma0, alpha0, beta0), means(sums.free, sigma0, alpha0, beta0)};
}

}  // namespace bgkmap::tune
