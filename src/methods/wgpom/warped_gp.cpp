#include "methods/wgpom/warped_gp.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <cstdio>
#include <cmath>
#include <limits>

#include "core/splitmix.hpp"
#include "methods/bhm/box_ascent.hpp"
#include "methods/gp/gp_cholesky.hpp"

namespace bgkmap {

namespace {
constexpr double kLog2Pi = 1.8378770664093453;
}  // namespace

double TanhWarp::value(double y) const {
  double g = d * y;
  for (size_t j = 0; j < a.size(); ++j) g += a[j] * std::tanh(b[j] * (y + c[j]));
  return g;
}

double TanhWarp::derivative(double y) const {
  double slope = d;
  for (size_t j = 0; j < a.size(); ++j) {
    const double t = std::tanh(b[j] * (y + c[j]));
    slope += a[j] * b[j] * (1 - t * t);
  }
  return slope;
}

double TanhWarp::inverse(double z, double guess) const {
  double reach = 0;
  for (const double aj : a) reach += aj;
  double lo = (z - reach) / d, hi = (z + reach) / d;
  double y = guess > lo && guess < hi ? guess : z / d;
  for (int iteration = 0; iteration < 200; ++iteration) {
    double g = d * y, slope = d;  // value and derivative, one exp per term
    for (size_t j = 0; j < a.size(); ++j) {
      const double t = 1 - 2 / (1 + std::exp(2 * b[j] * (y + c[j])));  // tanh, within 1e-16 absolute
      g += a[j] * t;
      slope += a[j] * b[j] * (1 - t * t);
    }
    const double f = g - z;
    if (f == 0) return y;
    (f > 0 ? hi : lo) = y;
    double next = y - f / slope;
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    // Newton converges quadratically: a step this small leaves the root within rounding.
    if (std::abs(next - y) <= 1e-10 * std::max(1.0, std::abs(y)) ||
        hi - lo <= 4 * std::numeric_limits<double>::epsilon() * std::max(1.0, std::abs(y)))
      return next;
    y = next;
  }
  return y;
}

std::vector<double> TanhWarp::parameters() const {
  std::vector<double> theta{std::log(d)};
  for (size_t j = 0; j < a.size(); ++j) theta.insert(theta.end(), {std::log(a[j]), std::log(b[j]), c[j]});
  return theta;
}

TanhWarp TanhWarp::from_parameters(const std::vector<double>& theta) {
  TanhWarp warp;
  warp.d = std::exp(theta.at(0));
  for (size_t k = 1; k + 2 < theta.size(); k += 3) {
    warp.a.push_back(std::exp(theta[k]));
    warp.b.push_back(std::exp(theta[k + 1]));
    warp.c.push_back(theta[k + 2]);
  }
  return warp;
}

std::string describe(const TanhWarp& warp) {
  char buffer[96];
  std::snprintf(buffer, sizeof buffer, "g(y) = %.4g y", warp.d);
  std::string out = buffer;
  for (size_t j = 0; j < warp.terms(); ++j) {
    std::snprintf(buffer, sizeof buffer, " + %.4g tanh(%.4g (y %c %.4g))", warp.a[j], warp.b[j], warp.c[j] < 0 ? '-' : '+',
                  std::abs(warp.c[j]));
    out += buffer;
  }
  return out;
}

WarpTrainingSet::WarpTrainingSet(std::vector<LocalModel> models, const GpHyperParams& hp) {
  models_ = models.size();
  // The distinct label values, and per model the indicator vector of each.
  for (const LocalModel& model : models)
    for (const double y : model.labels)
      if (std::find(values_.begin(), values_.end(), y) == values_.end()) values_.push_back(y);
  const size_t m = values_.size();
  counts_.assign(m, 0.0);
  quadratic_.assign(m * m, 0.0);
  for (const LocalModel& model : models) {
    const Eigen::LLT<Eigen::MatrixXd> llt = gp_factor(model.train, hp);
    log_det_ += 2 * llt.matrixLLT().diagonal().array().log().sum();
    labels_ += static_cast<double>(model.labels.size());
    const Eigen::Index n = static_cast<Eigen::Index>(model.labels.size());
    Eigen::MatrixXd indicators = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(m));
    for (Eigen::Index i = 0; i < n; ++i) {
      const size_t v = std::find(values_.begin(), values_.end(), model.labels[i]) - values_.begin();
      indicators(i, static_cast<Eigen::Index>(v)) = 1;
      counts_[v] += 1;
    }
    const Eigen::MatrixXd q = indicators.transpose() * llt.solve(indicators);
    for (size_t v = 0; v < m; ++v)
      for (size_t w = 0; w < m; ++w) quadratic_[v * m + w] += q(static_cast<Eigen::Index>(v), static_cast<Eigen::Index>(w));
  }
}

double WarpTrainingSet::log_likelihood(const TanhWarp& warp, std::vector<double>* gradient) const {
  const size_t terms = warp.terms(), m = values_.size();
  // z^T K~^-1 z summed over the models is sum_vw g(v) g(w) Q_vw; its gradient -(Q g)_v dg(v)/dtheta.
  std::vector<double> g(m), q_g(m, 0.0);
  for (size_t v = 0; v < m; ++v) g[v] = warp.value(values_[v]);
  double quadratic = 0;
  for (size_t v = 0; v < m; ++v) {
    for (size_t w = 0; w < m; ++w) q_g[v] += quadratic_[v * m + w] * g[w];
    quadratic += g[v] * q_g[v];
  }
  double sum = -0.5 * quadratic - 0.5 * log_det_ - 0.5 * labels_ * kLog2Pi;
  if (gradient) gradient->assign(1 + 3 * terms, 0.0);
  for (size_t v = 0; v < m; ++v) {
    const double y = values_[v], slope = warp.derivative(y), n = counts_[v];
    sum += n * std::log(slope);
    if (!gradient) continue;
    // d/dtheta of -1/2 z^T K~^-1 z: -(Q g)_v dg(v)/dtheta; of n_v log g'(v): n_v (dg'(v)/dtheta) / g'(v).
    (*gradient)[0] += -q_g[v] * warp.d * y + n * warp.d / slope;  // log d
    for (size_t j = 0; j < terms; ++j) {
      const double a = warp.a[j], b = warp.b[j], u = y + warp.c[j];
      const double t = std::tanh(b * u), sech2 = 1 - t * t, ab = a * b * sech2;
      double* d = gradient->data() + 1 + 3 * j;
      d[0] += -q_g[v] * a * t + n * ab / slope;                              // log a_j
      d[1] += -q_g[v] * ab * u + n * ab * (1 - 2 * b * u * t) / slope;       // log b_j
      d[2] += -q_g[v] * ab + n * (-2 * a * b * b * t * sech2) / slope;       // c_j
    }
  }
  return sum;
}

TanhWarp learn_warp(const WarpTrainingSet& set, const WarpLearning& options) {
  if (set.size() == 0 || options.terms <= 0) return {};
  const int terms = options.terms;
  // The box of each parameter: log d, then log a_j, log b_j, c_j.
  Box box{{std::log(options.d_range[0])}, {std::log(options.d_range[1])}};
  for (int j = 0; j < terms; ++j) {
    box.lo.insert(box.lo.end(), {std::log(options.a_range[0]), std::log(options.b_range[0]), options.c_range[0]});
    box.hi.insert(box.hi.end(), {std::log(options.a_range[1]), std::log(options.b_range[1]), options.c_range[1]});
  }
  // The first start is near the identity (d = 1, small terms spread over [-1, 1]), the others
  // uniform in the box.
  std::vector<std::vector<double>> starts;
  uint64_t counter = options.seed * 1000003;
  for (int restart = 0; restart < std::max(1, options.restarts); ++restart) {
    std::vector<double> theta(box.lo.size());
    for (size_t k = 0; k < theta.size(); ++k) {
      const int j = k == 0 ? 0 : static_cast<int>((k - 1) / 3);
      const double spread = terms > 1 ? -1.0 + 2.0 * j / (terms - 1) : 0.0;
      const double first = k == 0 ? 0.0 : (k - 1) % 3 == 0 ? std::log(0.1) : (k - 1) % 3 == 1 ? 0.0 : spread;
      theta[k] = restart == 0 ? first : box.lo[k] + (box.hi[k] - box.lo[k]) * unit_interval(splitmix64(counter++));
    }
    starts.push_back(theta);
  }
  const BoxObjective objective = [&](const std::vector<double>& theta, std::vector<double>& gradient) {
    return set.log_likelihood(TanhWarp::from_parameters(theta), &gradient);
  };
  return TanhWarp::from_parameters(maximise_in_box(objective, box, starts, options.max_iterations));
}

GpPrediction unwarp_prediction(double mean, double variance, const TanhWarp& warp, const GaussHermite& rule) {
  const double scale = variance > 0 ? std::sqrt(2 * variance) : 0.0, norm = 0.5641895835477563;  // 1 / sqrt(pi)
  const std::vector<double>& x = rule.nodes();
  const std::vector<double>& w = rule.weights();
  double y[100];
  double m = 0;
  for (int i = 0; i < rule.size(); ++i) {
    // The nodes ascend and the inverse is increasing: each solve starts from the previous root,
    // moved by the inverse's slope there.
    const double z = mean + scale * x[i];
    y[i] = warp.inverse(z, i > 0 ? y[i - 1] + (z - mean - scale * x[i - 1]) / warp.derivative(y[i - 1]) : NAN);
    m += w[i] * y[i];
  }
  m *= norm;
  double v = 0;
  for (int i = 0; i < rule.size(); ++i) v += w[i] * (y[i] - m) * (y[i] - m);
  GpPrediction p;
  p.mean = m;
  p.variance = v * norm;
  p.observed = true;
  return p;
}

}  // namespace bgkmap
