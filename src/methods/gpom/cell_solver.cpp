#include "methods/gpom/cell_solver.hpp"

namespace bgkmap::gpom {

GpPrediction mixture_moments(const std::vector<GpPrediction>& parts) {
  const double n = double(parts.size());
  GpPrediction m;
  for (const GpPrediction& p : parts) m.mean += p.mean / n;
  for (const GpPrediction& p : parts) m.variance += (p.variance + (p.mean - m.mean) * (p.mean - m.mean)) / n;
  return m;
}

GpPrediction CellSolver::latent(Scratch& s, size_t h, const Vec3d& q) const {
  const LocalModel& model = s.models[h];
  const InputUncertainty uncertain = uncertainty(s, h);
  return gp_predict(model.train, warp_.modelled(model.labels, s.warped), {models_.in_model(q, q)}, hp_,
                    kernel_ ? &uncertain : nullptr)[0];
}

void CellSolver::sample_leave_one_out(const Scratch& s, std::vector<LooSample>& out) const {
  std::vector<double> warped;
  for (size_t h = 0; h < s.models.size(); ++h) {
    const LocalModel& model = s.models[h];
    const InputUncertainty uncertain = uncertainty(s, h);
    const std::vector<GpPrediction> held_out =
        gp_leave_one_out(model.train, warp_.modelled(model.labels, warped), hp_, kernel_ ? &uncertain : nullptr);
    for (size_t i = 0; i < held_out.size(); ++i) {
      const GpPrediction sample = warp_.label_space(held_out[i]);
      out.push_back({model.labels[i], sample.mean, sample.variance});
    }
  }
}

GpomCell CellSolver::cell_of(const std::vector<GpPrediction>& latent, Scratch& s) const {
  s.parts.clear();
  for (const GpPrediction& p : latent) s.parts.push_back(warp_.label_space(p));
  const GpPrediction p = s.parts.size() == 1 ? s.parts[0] : mixture_moments(s.parts);
  return {p.mean, p.variance, true};
}

GpomCell CellSolver::unreached(const Vec3d& q) const {
  if (!prior_far_) return GpomCell{};
  const Vec3d x = models_.in_model(q, q);
  const GpPrediction p = warp_.label_space({0.0, gp_covariance(x, x, hp_), false});
  return {p.mean, p.variance, true};
}

}  // namespace bgkmap::gpom
