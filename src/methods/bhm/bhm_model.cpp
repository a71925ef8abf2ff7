#include "methods/bhm/bhm_model.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

namespace bgkmap {

namespace {

constexpr int kMaxSupportsPerBlock = 4096;  // two dense 4096^2 matrices: 268 MB per block
// The hinges in the box a point's features span: about 33 at the defaults in 2-D, under 3,000 for the
// smallest gamma --bhm-gamma 0 tries in 3-D.
constexpr double kMaxHingesPerPoint = 65536;

// int_0^length exp(-g |o + t d - c|^2) dt along the unit direction d: erf in closed form.
double gaussian_line_integral(double ox, double oy, double dx, double dy, double length, double cx, double cy,
                              double g) {
  const double px = cx - ox, py = cy - oy;
  const double t0 = px * dx + py * dy;  // where the line passes closest to c
  const double perp2 = std::max(0.0, px * px + py * py - t0 * t0);
  const double s = std::sqrt(g);
  return std::exp(-g * perp2) * (0.5 * std::sqrt(M_PI) / s) * (std::erf(s * (length - t0)) + std::erf(s * t0));
}

}  // namespace

double jj_lambda(double xi) {
  xi = std::abs(xi);
  if (xi < 1e-6) return 0.125 - xi * xi / 96.0;  // Taylor: tanh(x/2)/(4x) = 1/8 - x^2/96 + ...
  return std::tanh(0.5 * xi) / (4.0 * xi);
}

double BhmModel::probability(const BhmLogit& a) {
  const double kappa = 1.0 / std::sqrt(1.0 + M_PI * a.variance / 8.0);
  return 1.0 / (1.0 + std::exp(-kappa * a.mean));
}

BhmModel::BhmModel(const BhmParams& params, std::shared_ptr<BlockGramEngine> gram) : p_(params), gram_(std::move(gram)) {
  if (!(p_.spacing_m > 0 && std::isfinite(p_.spacing_m))) throw std::invalid_argument("bhm-spacing must be > 0 and finite");
  if (!(p_.gamma > 0 && std::isfinite(p_.gamma))) throw std::invalid_argument("bhm-gamma must be > 0 and finite");
  if (!(p_.support_var >= 0 && std::isfinite(p_.support_var)))
    throw std::invalid_argument("bhm-support-var must be >= 0 and finite");
  if (!(p_.support_side >= 0 && std::isfinite(p_.support_side)))
    throw std::invalid_argument("bhm-support-side must be >= 0 and finite");
  if (p_.support_var > 0 && p_.support_side > 0)
    throw std::invalid_argument("bhm-support-var (Gaussian supports) and bhm-support-side (rectangles) exclude each other");
  if (!(p_.prior_var >= kMinBhmPriorVar && p_.prior_var <= kMaxBhmPriorVar)) {
    char text[80];
    std::snprintf(text, sizeof text, "bhm-prior-var must be in [%g, %g]", kMinBhmPriorVar, kMaxBhmPriorVar);
    throw std::invalid_argument(text);
  }
  if (p_.em_iterations < 1) throw std::invalid_argument("bhm-em-iterations must be >= 1");
  if (p_.dims != 2 && p_.dims != 3) throw std::invalid_argument("bhm: dims must be 2 or 3");
  if (p_.block_side < 1) throw std::invalid_argument("bhm-block-side must be >= 1");
  const double supports = std::pow(double(p_.block_side), p_.dims);
  if (supports > kMaxSupportsPerBlock)
    throw std::invalid_argument("bhm-block-side " + std::to_string(p_.block_side) + " gives " +
                                std::to_string(int64_t(supports)) + " supports per block in " +
                                std::to_string(p_.dims) + "-D; at most " + std::to_string(kMaxSupportsPerBlock) +
                                " (two dense covariance-sized matrices per block)");
  m_ = static_cast<int>(supports);
  // E over h ~ N(h0, s I) of exp(-gamma |x - h|^2) = (1 + 2 gamma s)^(-d/2) exp(-gamma |x - h0|^2 / (1 + 2 gamma s)).
  const double spread = 1.0 + 2.0 * p_.gamma * p_.support_var;
  gamma_eff_ = p_.gamma / spread;
  amplitude_ = std::pow(spread, -0.5 * p_.dims);
  reach_ = amplitude_ > kFeatureCutoff ? std::sqrt(std::log(amplitude_ / kFeatureCutoff) / gamma_eff_) : 0.0;
  if (p_.support_side > 0) {
    // The largest offset along one axis at which a feature can reach the cutoff (the other axes
    // at their peak): rectangle_factor decreases in |delta|, so bisect.
    const double peak = std::pow(rectangle_factor(0.0), p_.dims - 1);
    double lo = 0, hi = 0.5 * p_.support_side + 10.0 / std::sqrt(p_.gamma);
    if (peak * rectangle_factor(0.0) < kFeatureCutoff) hi = 0;
    for (int i = 0; i < 100 && hi > 0; ++i) {
      const double mid = 0.5 * (lo + hi);
      (peak * rectangle_factor(mid) >= kFeatureCutoff ? lo : hi) = mid;
    }
    reach_ = hi;
  }
  // Every hinge within reach of a point is one of its features, visited by each update and by
  // its memory estimate: a spacing far below the reach is refused here, before either.
  const double hinges = std::pow(2 * reach_ / p_.spacing_m + 1, p_.dims);
  if (hinges > kMaxHingesPerPoint) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "bhm-spacing %g m puts %.3g hinges within reach of a point (%.3g m, from bhm-gamma and the "
                  "supports), at most %.0f: give a larger bhm-spacing",
                  p_.spacing_m, hinges, reach_, kMaxHingesPerPoint);
    throw std::invalid_argument(text);
  }
  if (p_.threads < 1) p_.threads = 1;
  bias_var_ = p_.prior_var;
  if (!gram_) gram_ = make_cpu_block_gram(p_.threads);
}

double BhmModel::rectangle_factor(double delta) const {
  const double s = std::sqrt(p_.gamma), half = 0.5 * p_.support_side;
  return 0.5 * std::sqrt(M_PI) / (s * p_.support_side) * (std::erf(s * (delta + half)) - std::erf(s * (delta - half)));
}

double BhmModel::feature(const Vec3d& x, const Vec3d& hinge) const {
  const double dz = p_.dims == 2 ? 0.0 : x.z - hinge.z;
  if (p_.support_side > 0) {
    double v = rectangle_factor(x.x - hinge.x) * rectangle_factor(x.y - hinge.y);
    return p_.dims == 2 ? v : v * rectangle_factor(dz);
  }
  const double dx = x.x - hinge.x, dy = x.y - hinge.y;
  return feature_value(dx * dx + dy * dy + dz * dz);
}

void BhmModel::hinge_range(const Vec3d& x, int32_t lo[3], int32_t hi[3]) const {
  const double c[3] = {x.x, x.y, x.z};
  for (int a = 0; a < 3; ++a) {
    if (a == 2 && p_.dims == 2) {
      lo[a] = hi[a] = 0;
      continue;
    }
    lo[a] = static_cast<int32_t>(std::ceil((c[a] - reach_) / p_.spacing_m));
    hi[a] = static_cast<int32_t>(std::floor((c[a] + reach_) / p_.spacing_m));
  }
}

Vec3d BhmModel::hinge_position(const BlockKey& block, int local) const {
  const int s = p_.block_side;
  const int32_t i = block.x * s + local % s, j = block.y * s + (local / s) % s;
  if (p_.dims == 2) return {i * p_.spacing_m, j * p_.spacing_m, p_.plane_z};
  const int32_t k = block.z * s + local / (s * s);
  return {i * p_.spacing_m, j * p_.spacing_m, k * p_.spacing_m};
}

void BhmModel::features(const Vec3d& x, std::vector<Feature>& out) const {
  out.clear();
  int32_t lo[3], hi[3];
  hinge_range(x, lo, hi);
  const int s = p_.block_side;
  const double r2 = reach_ * reach_;
  for (int32_t k = lo[2]; k <= hi[2]; ++k) {
    const double dz = p_.dims == 2 ? 0.0 : x.z - k * p_.spacing_m;
    for (int32_t j = lo[1]; j <= hi[1]; ++j) {
      const double dy = x.y - j * p_.spacing_m;
      for (int32_t i = lo[0]; i <= hi[0]; ++i) {
        const double dx = x.x - i * p_.spacing_m;
        const Vec3d hinge{i * p_.spacing_m, j * p_.spacing_m, p_.dims == 2 ? p_.plane_z : k * p_.spacing_m};
        double value;
        if (p_.support_side > 0) {  // a product of per-axis factors: cut where it is below the cutoff
          value = feature(x, hinge);
          if (value < kFeatureCutoff) continue;
        } else {
          const double d2 = dx * dx + dy * dy + dz * dz;
          if (d2 > r2) continue;
          value = feature_value(d2);
        }
        const BlockKey block{floor_div(i, s), floor_div(j, s), p_.dims == 2 ? 0 : floor_div(k, s)};
        const int local = (i - block.x * s) + s * ((j - block.y * s) + s * (k - block.z * s));
        out.push_back({block, local, value, hinge});
      }
    }
  }
}

void BhmModel::beam_integrals(const BhmBeam& beam, std::vector<Feature>& supports,
                              std::vector<BeamPair>& pairs) const {
  supports.clear();
  pairs.clear();
  if (p_.dims != 2) throw std::invalid_argument("bhm: free beams are for 2-D maps only");
  if (p_.support_side > 0) throw std::invalid_argument("bhm: free beams need RBF or Gaussian supports, not rectangles");
  const double ox = beam.from.x, oy = beam.from.y;
  const double length = std::hypot(beam.to.x - ox, beam.to.y - oy);
  if (!(length > 1e-9) || reach_ <= 0) return;
  const double dx = (beam.to.x - ox) / length, dy = (beam.to.y - oy) / length;
  const double h = p_.spacing_m, r2 = reach_ * reach_;
  const int32_t i0 = static_cast<int32_t>(std::ceil((std::min(ox, beam.to.x) - reach_) / h));
  const int32_t i1 = static_cast<int32_t>(std::floor((std::max(ox, beam.to.x) + reach_) / h));
  const int32_t j0 = static_cast<int32_t>(std::ceil((std::min(oy, beam.to.y) - reach_) / h));
  const int32_t j1 = static_cast<int32_t>(std::floor((std::max(oy, beam.to.y) + reach_) / h));
  const int s = p_.block_side;
  std::unordered_map<int64_t, uint32_t> at;  // hinge (i, j) -> its number in supports
  const auto key = [](int32_t i, int32_t j) {
    return static_cast<int64_t>((uint64_t{static_cast<uint32_t>(i)} << 32) | static_cast<uint32_t>(j));
  };
  std::vector<std::pair<int32_t, int32_t>> ij;
  for (int32_t j = j0; j <= j1; ++j)
    for (int32_t i = i0; i <= i1; ++i) {
      const double px = i * h - ox, py = j * h - oy;
      const double t = std::clamp(px * dx + py * dy, 0.0, length);
      const double ex = px - t * dx, ey = py - t * dy;
      if (ex * ex + ey * ey > r2) continue;
      const BlockKey block{floor_div(i, s), floor_div(j, s), 0};
      const int local = (i - block.x * s) + s * (j - block.y * s);
      at.emplace(key(i, j), static_cast<uint32_t>(supports.size()));
      ij.emplace_back(i, j);
      supports.push_back({block, local,
                          amplitude_ * gaussian_line_integral(ox, oy, dx, dy, length, i * h, j * h, gamma_eff_),
                          {i * h, j * h, p_.plane_z}});
    }
  // phi_a phi_b = amplitude^2 exp(-gamma |h_a - h_b|^2 / 2) exp(-2 gamma |x - (h_a + h_b) / 2|^2).
  const int32_t span = static_cast<int32_t>(std::floor(2.0 * reach_ / h));
  for (uint32_t a = 0; a < supports.size(); ++a)
    for (int32_t dj = -span; dj <= span; ++dj)
      for (int32_t di = -span; di <= span; ++di) {
        const double d2 = (double(di) * di + double(dj) * dj) * h * h;
        if (d2 > 4.0 * r2) continue;
        const auto it = at.find(key(ij[a].first + di, ij[a].second + dj));
        if (it == at.end() || it->second < a) continue;
        const uint32_t b = it->second;
        const double mx = 0.5 * (supports[a].hinge.x + supports[b].hinge.x);
        const double my = 0.5 * (supports[a].hinge.y + supports[b].hinge.y);
        pairs.push_back({a, b,
                         amplitude_ * amplitude_ * std::exp(-0.5 * gamma_eff_ * d2) *
                             gaussian_line_integral(ox, oy, dx, dy, length, mx, my, 2.0 * gamma_eff_)});
      }
}

// Per (point, support) entry a support index and a feature value, held by the rows and copied
// for the Gram engine (48 bytes with the arrays' doubling; on average the hinges in the features'
// ball, the whole box for rectangle supports), per (point, block) row 60 bytes, per point 24; per
// reached block a copy of its prior precision and vectors, one batch of Gram matrices, per new
// block its mean, covariance and precision, and one precision being solved per thread.
double BhmModel::update_bytes(const std::vector<Vec3d>& points, const std::vector<BhmBeam>& beams,
                              size_t* reached_blocks) const {
  const double m = m_, reach = reach_, spacing = p_.spacing_m;
  const double ball = p_.dims == 2 ? M_PI * reach * reach / (spacing * spacing)
                                   : 4.0 / 3.0 * M_PI * reach * reach * reach / (spacing * spacing * spacing);
  // Counted, not listed: the entries and rows, then the distinct blocks reached, marked in a
  // bitmap over the blocks' bounding box (an upper bound when that box or the rows are too many
  // to mark, which a memory limit then refuses anyway).
  const auto block_range = [&](const Vec3d& x, int32_t lo[3], int32_t hi[3]) {
    hinge_range(x, lo, hi);
    for (int a = 0; a < 3; ++a) {
      lo[a] = floor_div(lo[a], p_.block_side);
      hi[a] = floor_div(hi[a], p_.block_side);
    }
  };
  double entries = 0, rows = 0;
  int64_t box_lo[3] = {INT64_MAX, INT64_MAX, INT64_MAX}, box_hi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
  for (const Vec3d& x : points) {
    int32_t lo[3], hi[3];
    hinge_range(x, lo, hi);
    double hinges = 1;
    for (int a = 0; a < p_.dims; ++a) hinges *= std::max(0.0, double(hi[a]) - lo[a] + 1);
    entries += p_.support_side > 0 ? hinges : std::min(hinges, ball);
    block_range(x, lo, hi);
    double blocks = 1;
    for (int a = 0; a < 3; ++a) {
      blocks *= std::max(0.0, double(hi[a]) - lo[a] + 1);
      box_lo[a] = std::min<int64_t>(box_lo[a], lo[a]);
      box_hi[a] = std::max<int64_t>(box_hi[a], hi[a]);
    }
    rows += blocks;
  }
  double reached = 0, fresh = 0;
  if (!points.empty()) {
    const int64_t side[3] = {box_hi[0] - box_lo[0] + 1, box_hi[1] - box_lo[1] + 1, box_hi[2] - box_lo[2] + 1};
    const double box = double(side[0]) * double(side[1]) * double(side[2]);
    constexpr double kMostMarked = double(int64_t{1} << 27);  // 16 MB of bits; as many row visits
    if (box > kMostMarked || rows > kMostMarked) {
      reached = fresh = std::min(rows, box);
    } else {
      std::vector<bool> marked(static_cast<size_t>(box), false);
      for (const Vec3d& x : points) {
        int32_t lo[3], hi[3];
        block_range(x, lo, hi);
        for (int64_t z = lo[2]; z <= hi[2]; ++z)
          for (int64_t y = lo[1]; y <= hi[1]; ++y)
            for (int64_t bx = lo[0]; bx <= hi[0]; ++bx)
              marked[size_t(((z - box_lo[2]) * side[1] + (y - box_lo[1])) * side[0] + (bx - box_lo[0]))] = true;
      }
      for (size_t i = 0; i < marked.size(); ++i) {
        if (!marked[i]) continue;
        ++reached;
        const int64_t bx = int64_t(i) % side[0], y = int64_t(i) / side[0] % side[1], z = int64_t(i) / side[0] / side[1];
        const BlockKey key{int32_t(bx + box_lo[0]), int32_t(y + box_lo[1]), int32_t(z + box_lo[2])};
        if (find_block(key) < 0) ++fresh;
      }
    }
  }
  const double gram_blocks = std::min(reached, std::max(1.0, double(kMaxGramBatchBytes) / (m * m * 8)));
  if (reached_blocks) *reached_blocks = static_cast<size_t>(reached);
  // A free beam (2-D): its supports, the hinges within reach of the segment (a strip `across`
  // hinges wide; 48 bytes each with their line integrals, 12 more in the block's rows), and its
  // pairs (a <= b), each support with those of the strip within twice the reach (16 bytes, and
  // 24 in each of the two blocks' rows).
  const double across = 2 * reach / spacing + 1, pair_span = 4 * reach / spacing + 1;
  double beam_bytes = 0;
  for (const BhmBeam& beam : beams) {
    const double supports = (std::hypot(beam.to.x - beam.from.x, beam.to.y - beam.from.y) / spacing + across) * across;
    beam_bytes += supports * (48 + 12) + supports * std::min(supports, pair_span * across) / 2 * (16 + 2 * 24);
  }
  return beam_bytes + entries * 48 + rows * 60 + double(points.size()) * 24 + reached * (m * m + 3 * m) * 8 +
         gram_blocks * (m * m + m) * 8 + fresh * (2 * m * m + m) * 8 + double(std::max(1, p_.threads)) * m * m * 8;
}

int64_t BhmModel::find_block(const BlockKey& key) const {
  const uint32_t b = index_.find(key);
  return b == BlockIndex::kAbsent ? -1 : int64_t{b};
}

uint32_t BhmModel::ensure_block(const BlockKey& key) {
  return index_.find_or_insert(key, [&] {
    Block block;  // the prior N(0, prior_var I)
    block.mean = Eigen::VectorXd::Zero(m_);
    block.cov = Eigen::MatrixXd::Identity(m_, m_) * p_.prior_var;
    block.precision = Eigen::MatrixXd::Identity(m_, m_) / p_.prior_var;
    blocks_.push_back(std::move(block));
  });
}

std::optional<BhmLogit> BhmModel::logit(const Vec3d& x) const {
  thread_local std::vector<Feature> f;
  features(x, f);
  BhmLogit a;
  bool known = false;
  std::vector<bool> done(f.size(), false);
  for (size_t i = 0; i < f.size(); ++i) {
    if (done[i]) continue;
    const int64_t b = find_block(f[i].block);
    // The features of this block: i and every later one with the same key.
    std::vector<size_t> same;
    for (size_t j = i; j < f.size(); ++j)
      if (!done[j] && f[j].block == f[i].block) {
        same.push_back(j);
        done[j] = true;
      }
    if (b < 0) {  // never updated: the prior N(0, prior_var I)
      for (size_t j : same) a.variance += p_.prior_var * f[j].value * f[j].value;
      continue;
    }
    known = true;
    const Block& block = blocks_[b];
    for (size_t u : same) {
      a.mean += f[u].value * block.mean[f[u].local];
      for (size_t v : same) a.variance += f[u].value * f[v].value * block.cov(f[u].local, f[v].local);
    }
  }
  if (!known) return std::nullopt;
  if (p_.bias) {
    a.mean += bias_mean_;
    a.variance += bias_var_;
  }
  return a;
}

}  // namespace bgkmap
