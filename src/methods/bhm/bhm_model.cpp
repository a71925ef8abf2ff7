#include "methods/bhm/bhm_model.hpp"

#include <omp.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <tuple>
#include <unordered_map>

#include "core/parallel_errors.hpp"

namespace bgkmap {

namespace {

constexpr int kMaxSupportsPerBlock = 4096;  // two dense 4096^2 matrices: 268 MB per block
// The hinges in the box a point's features span: about 33 at the defaults in 2-D, under 3,000 for the
// smallest gamma --bhm-gamma 0 tries in 3-D.
constexpr double kMaxHingesPerPoint = 65536;

// The rows one block sees in one scan: for each (point, block) pair, its nonzero features.
struct BlockRows {
  uint32_t block = 0;
  std::vector<uint32_t> point;       // row -> point
  std::vector<uint32_t> begin{0};    // row -> first entry; begin[rows] = entries
  std::vector<int> local;            // entry -> support within the block
  std::vector<double> value;         // entry -> feature value
  std::vector<double> mean, var;     // row -> this block's part of the logit's mean and variance
  std::vector<double> old_mean;      // mean before this colour's update
  Eigen::VectorXd next_mean;         // this colour's new mean, committed once all its blocks are done
  // Free beams: the beams reaching this block (in scan order), their supports here with the line
  // integrals g, and their Gram entries G(u, v) for u here (other: the touched block of v; -1 here).
  struct Pair {
    int u, v;
    int32_t other;
    double value;
  };
  std::vector<uint32_t> beam;
  std::vector<uint32_t> g_begin, pair_begin;  // beam entry -> first g / pair; one past the last at the end
  std::vector<int> g_local;
  std::vector<double> g_value;
  std::vector<Pair> pairs;
  std::vector<double> beam_moment;    // beam entry -> this block's part of int E[a^2] dt
  Eigen::VectorXd prior_rhs;         // P0 mu0 (the scan's prior)
  Eigen::MatrixXd prior_precision;   // P0
  Eigen::VectorXd prior_mean;        // mu0 (for the ELBO)
  double log_det_precision = 0;      // log |P| of the last q update (for the ELBO)
  int colour = 0;
  size_t rows() const { return point.size(); }
};

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
  return a;
}

BhmUpdateStats BhmModel::update(const std::vector<Vec3d>& points, const std::vector<double>& labels,
                                const std::vector<BhmBeam>& beams, double beam_density,
                                const std::vector<double>* fixed_xi) {
  BhmUpdateStats stats;
  if (points.empty() && beams.empty()) return stats;
  if (!beams.empty() && p_.dims != 2) throw std::invalid_argument("bhm: free beams are for 2-D maps only");
  if (!beams.empty() && !(beam_density > 0)) throw std::invalid_argument("bhm: beam density must be > 0");
  if (!beams.empty() && p_.support_side > 0)
    throw std::invalid_argument("bhm: free beams need RBF or Gaussian supports, not rectangles");
  // The beams' line integrals first, in parallel: an exp and two erf per (beam, support) and per pair.
  const int64_t beam_count = static_cast<int64_t>(beams.size());
  std::vector<std::vector<Feature>> beam_supports(beams.size());
  std::vector<std::vector<BeamPair>> beam_pairs(beams.size());
  std::vector<double> beam_length(beams.size());
  ParallelErrors errors;
#pragma omp parallel for schedule(dynamic, 4) num_threads(p_.threads)
  for (int64_t k = 0; k < beam_count; ++k)
    errors.run([&] {
      beam_integrals(beams[k], beam_supports[k], beam_pairs[k]);
      beam_length[k] = std::hypot(beams[k].to.x - beams[k].from.x, beams[k].to.y - beams[k].from.y);
    });
  errors.rethrow();

  // Rows per touched block, points in order (a counting sort of (block, point, entry) by block).
  std::vector<int32_t> touched_of(blocks_.size(), -1);
  std::vector<BlockRows> rows;
  const auto touch = [&](const BlockKey& key) -> int32_t {
    const uint32_t b = ensure_block(key);
    if (b >= touched_of.size()) touched_of.resize(b + 1, -1);
    if (touched_of[b] < 0) {
      touched_of[b] = static_cast<int32_t>(rows.size());
      rows.emplace_back();
      rows.back().block = b;
    }
    return touched_of[b];
  };
  std::vector<Feature> f;
  for (uint32_t p = 0; p < points.size(); ++p) {
    features(points[p], f);
    for (const Feature& feature : f) {
      BlockRows& r = rows[touch(feature.block)];
      if (r.point.empty() || r.point.back() != p) {
        if (!r.point.empty()) r.begin.push_back(static_cast<uint32_t>(r.local.size()));
        r.point.push_back(p);
      }
      r.local.push_back(feature.local);
      r.value.push_back(feature.value);
    }
  }
  std::vector<int32_t> support_row;
  for (uint32_t k = 0; k < beams.size(); ++k) {
    support_row.resize(beam_supports[k].size());
    for (size_t a = 0; a < beam_supports[k].size(); ++a) {
      const Feature& support = beam_supports[k][a];
      const int32_t t = support_row[a] = touch(support.block);
      BlockRows& r = rows[t];
      if (r.beam.empty() || r.beam.back() != k) {
        r.beam.push_back(k);
        r.g_begin.push_back(static_cast<uint32_t>(r.g_local.size()));
        r.pair_begin.push_back(static_cast<uint32_t>(r.pairs.size()));
      }
      r.g_local.push_back(support.local);
      r.g_value.push_back(support.value);
    }
    for (const BeamPair& pair : beam_pairs[k]) {
      const int32_t ta = support_row[pair.a], tb = support_row[pair.b];
      const int ua = beam_supports[k][pair.a].local, ub = beam_supports[k][pair.b].local;
      rows[ta].pairs.push_back({ua, ub, ta == tb ? -1 : tb, pair.value});
      if (pair.a != pair.b) rows[tb].pairs.push_back({ub, ua, ta == tb ? -1 : ta, pair.value});
    }
  }
  const int64_t touched = static_cast<int64_t>(rows.size());
  for (BlockRows& r : rows) {
    r.begin.push_back(static_cast<uint32_t>(r.local.size()));
    r.g_begin.push_back(static_cast<uint32_t>(r.g_local.size()));
    r.pair_begin.push_back(static_cast<uint32_t>(r.pairs.size()));
    r.mean.assign(r.rows(), 0.0);
    r.var.assign(r.rows(), 0.0);
    r.beam_moment.assign(r.beam.size(), 0.0);
    const Block& block = blocks_[r.block];
    r.prior_precision = block.precision;
    r.prior_rhs = block.precision * block.mean;
    if (p_.elbo) r.prior_mean = block.mean;
    const BlockKey& k = index_.key(r.block);
    r.colour = (k.x & 1) | ((k.y & 1) << 1) | ((k.z & 1) << 2);
    stats.rows += r.rows() + r.g_local.size();
  }
  stats.blocks = rows.size();

  // This block's part of each row's logit mean and variance, and of each beam's int E[a^2] dt,
  // under the current q.
  const auto refresh_rows = [&](BlockRows& r) {
    const Block& block = blocks_[r.block];
    for (size_t row = 0; row < r.rows(); ++row) {
      double mean = 0, var = 0;
      for (uint32_t u = r.begin[row]; u < r.begin[row + 1]; ++u) {
        mean += r.value[u] * block.mean[r.local[u]];
        double inner = 0;
        for (uint32_t v = r.begin[row]; v < r.begin[row + 1]; ++v) inner += r.value[v] * block.cov(r.local[u], r.local[v]);
        var += r.value[u] * inner;
      }
      r.mean[row] = mean;
      r.var[row] = var;
    }
  };
  const auto refresh_beam_moments = [&](BlockRows& r) {
    const Block& block = blocks_[r.block];
    for (size_t e = 0; e < r.beam.size(); ++e) {
      double moment = 0;
      for (uint32_t q = r.pair_begin[e]; q < r.pair_begin[e + 1]; ++q) {
        const BlockRows::Pair& pair = r.pairs[q];
        const double other_mean =
            pair.other < 0 ? block.mean[pair.v] : blocks_[rows[pair.other].block].mean[pair.v];
        moment += pair.value * ((pair.other < 0 ? block.cov(pair.u, pair.v) : 0.0) + block.mean[pair.u] * other_mean);
      }
      r.beam_moment[e] = moment;
    }
  };
  // The point rows of every touched block, blocks by colour (colour_begin[c] is colour c's first),
  // for the Gram engine; gram_row[t]: block t's first row there.
  const int colours = p_.dims == 2 ? 4 : 8;
  std::vector<uint32_t> gram_order, colour_begin(colours + 1, 0), gram_row(rows.size());
  // Local to the update: the engines read the rows only within this update's calls.
  BlockGramRows gram_rows;
  gram_rows.m = m_;
  for (int c = 0; c < colours; ++c) {
    colour_begin[c] = static_cast<uint32_t>(gram_order.size());
    for (size_t t = 0; t < rows.size(); ++t) {
      if (rows[t].colour != c) continue;
      const BlockRows& r = rows[t];
      gram_order.push_back(static_cast<uint32_t>(t));
      gram_row[t] = static_cast<uint32_t>(gram_rows.rows());
      for (size_t row = 0; row < r.rows(); ++row)
        gram_rows.row_begin.push_back(gram_rows.row_begin.back() + (r.begin[row + 1] - r.begin[row]));
      gram_rows.column.insert(gram_rows.column.end(), r.local.begin(), r.local.end());
      gram_rows.value.insert(gram_rows.value.end(), r.value.begin(), r.value.end());
      gram_rows.block_row_begin.push_back(static_cast<uint32_t>(gram_rows.rows()));
    }
  }
  colour_begin[colours] = static_cast<uint32_t>(gram_order.size());
  gram_->set_rows(gram_rows);
  std::vector<double> gram_weight(gram_rows.rows()), gram_target(gram_rows.rows()), gram, gram_rhs;

  // q_b given its point rows' sums (gram, rhs: 2 Phi^T Lambda Phi and the targets' Phi^T t) and,
  // for beams, lambda and the other blocks' means.
  const double density = beam_density;
  const auto update_block = [&](BlockRows& r, const double* gram_b, const double* rhs_b,
                                const std::vector<double>& beam_lambda) {
    Eigen::MatrixXd precision = r.prior_precision + Eigen::Map<const Eigen::MatrixXd>(gram_b, m_, m_);
    Eigen::VectorXd rhs = r.prior_rhs + Eigen::Map<const Eigen::VectorXd>(rhs_b, m_);
    for (size_t e = 0; e < r.beam.size(); ++e) {
      const double weight = 2.0 * density * beam_lambda[r.beam[e]];
      for (uint32_t q = r.g_begin[e]; q < r.g_begin[e + 1]; ++q) rhs[r.g_local[q]] -= 0.5 * density * r.g_value[q];
      for (uint32_t q = r.pair_begin[e]; q < r.pair_begin[e + 1]; ++q) {
        const BlockRows::Pair& pair = r.pairs[q];
        if (pair.other < 0) precision(pair.u, pair.v) += weight * pair.value;
        else rhs[pair.u] -= weight * pair.value * blocks_[rows[pair.other].block].mean[pair.v];
      }
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(precision);
    if (llt.info() != Eigen::Success) throw std::runtime_error("bhm: a block's posterior precision is not positive definite");
    Block& block = blocks_[r.block];
    if (p_.elbo) r.log_det_precision = 2.0 * llt.matrixLLT().diagonal().array().log().sum();
    r.next_mean = llt.solve(rhs);
    block.cov = llt.solve(Eigen::MatrixXd::Identity(m_, m_));
    block.precision = std::move(precision);
  };

  std::vector<double> logit_mean(points.size(), 0.0), logit_var(points.size(), 0.0), lambda(points.size());
  std::vector<double> beam_moment(beams.size(), 0.0), beam_lambda(beams.size());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
  for (int64_t t = 0; t < touched; ++t) refresh_rows(rows[t]);
  const auto sum_rows = [&](bool beam_moments) {
    std::fill(logit_mean.begin(), logit_mean.end(), 0.0);
    std::fill(logit_var.begin(), logit_var.end(), 0.0);
    for (const BlockRows& r : rows)
      for (size_t row = 0; row < r.rows(); ++row) {
        logit_mean[r.point[row]] += r.mean[row];
        logit_var[r.point[row]] += r.var[row];
      }
    if (beams.empty() || !beam_moments) return;
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t) refresh_beam_moments(rows[t]);
    std::fill(beam_moment.begin(), beam_moment.end(), 0.0);
    for (const BlockRows& r : rows)
      for (size_t e = 0; e < r.beam.size(); ++e) beam_moment[r.beam[e]] += r.beam_moment[e];
  };
  sum_rows(true);
  const int iterations = fixed_xi ? 1 : p_.em_iterations;
  for (int it = 0; it < iterations; ++it) {
    // E: xi^2 = E[a^2] under the current q (a beam's: its mean along the beam).
    for (size_t p = 0; p < points.size(); ++p)
      lambda[p] = jj_lambda(fixed_xi ? (*fixed_xi)[p] : std::sqrt(logit_var[p] + logit_mean[p] * logit_mean[p]));
    for (size_t k = 0; k < beams.size(); ++k)
      beam_lambda[k] = jj_lambda(fixed_xi ? (*fixed_xi)[points.size() + k]
                                          : std::sqrt(std::max(0.0, beam_moment[k]) / std::max(beam_length[k], 1e-12)));
    // M: blocks of one colour (no two of them reached by one point when the reach is at most a
    // block's side) together, the colours in turn, each seeing the others' newest means. A colour's
    // new means are committed after all its blocks are solved, so none reads a half-written one.
    for (int c = 0; c < colours; ++c) {
      const uint32_t first = colour_begin[c], last = colour_begin[c + 1];
      if (first == last) continue;
      // A point's row in block b: weight 2 lambda, target y - 1/2 - 2 lambda (the other blocks'
      // part of its logit mean).
      for (uint32_t g = first; g < last; ++g) {
        const BlockRows& r = rows[gram_order[g]];
        for (size_t row = 0; row < r.rows(); ++row) {
          const uint32_t p = r.point[row];
          const double two_lambda = 2.0 * lambda[p];
          gram_weight[gram_row[gram_order[g]] + row] = two_lambda;
          gram_target[gram_row[gram_order[g]] + row] = labels[p] - 0.5 - two_lambda * (logit_mean[p] - r.mean[row]);
        }
      }
      // The colour's Gram matrices in batches of at most kMaxGramBatchBytes (one block at least).
      const size_t mm = size_t(m_) * size_t(m_);
      const uint32_t batch = static_cast<uint32_t>(std::max<size_t>(1, kMaxGramBatchBytes / (mm * sizeof(double))));
      for (uint32_t b0 = first; b0 < last; b0 += batch) {
        const uint32_t b1 = std::min(last, b0 + batch);
        gram.resize((b1 - b0) * mm);
        gram_rhs.resize((b1 - b0) * size_t(m_));
        gram_->accumulate(b0, b1, gram_weight, gram_target, gram.data(), gram_rhs.data());
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
        for (int64_t g = b0; g < int64_t{b1}; ++g)
          errors.run([&] {
            update_block(rows[gram_order[g]], gram.data() + (g - b0) * mm, gram_rhs.data() + (g - b0) * size_t(m_),
                         beam_lambda);
          });
        errors.rethrow();
      }
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
      for (int64_t t = 0; t < touched; ++t)
        if (rows[t].colour == c)
          errors.run([&] {
            BlockRows& r = rows[t];
            blocks_[r.block].mean.swap(r.next_mean);
            r.old_mean = r.mean;
            refresh_rows(r);
          });
      errors.rethrow();
      for (const BlockRows& r : rows)
        if (r.colour == c)
          for (size_t row = 0; row < r.rows(); ++row) logit_mean[r.point[row]] += r.mean[row] - r.old_mean[row];
    }
    sum_rows(it + 1 < iterations || (p_.elbo && !beams.empty()));  // the beams' moments for an E step or the ELBO
  }
  if (p_.elbo) {
    // log sigma(xi) - xi / 2 at xi = sqrt(E[a^2]), where the bound's lambda term vanishes.
    const auto log_sigmoid_minus_half = [](double xi) { return -std::log1p(std::exp(-xi)) - 0.5 * xi; };
    double elbo = 0;
    for (size_t p = 0; p < points.size(); ++p)
      elbo += (labels[p] - 0.5) * logit_mean[p] +
              log_sigmoid_minus_half(std::sqrt(std::max(0.0, logit_var[p] + logit_mean[p] * logit_mean[p])));
    std::vector<double> beam_mean(beams.size(), 0.0);  // int E[a] dt
    for (const BlockRows& r : rows)
      for (size_t e = 0; e < r.beam.size(); ++e)
        for (uint32_t q = r.g_begin[e]; q < r.g_begin[e + 1]; ++q)
          beam_mean[r.beam[e]] += r.g_value[q] * blocks_[r.block].mean[r.g_local[q]];
    for (size_t k = 0; k < beams.size(); ++k) {
      const double length = std::max(beam_length[k], 1e-12);
      elbo += density * (-0.5 * beam_mean[k] +
                         length * log_sigmoid_minus_half(std::sqrt(std::max(0.0, beam_moment[k]) / length)));
    }
    std::vector<double> kl(rows.size(), 0.0);
#pragma omp parallel for schedule(dynamic) num_threads(p_.threads)
    for (int64_t t = 0; t < touched; ++t)
      errors.run([&] {
        const BlockRows& r = rows[t];
        const Block& block = blocks_[r.block];
        const Eigen::LLT<Eigen::MatrixXd> prior(r.prior_precision);
        const double log_det_prior = 2.0 * prior.matrixLLT().diagonal().array().log().sum();
        const Eigen::VectorXd d = block.mean - r.prior_mean;
        kl[t] = 0.5 * (r.prior_precision.cwiseProduct(block.cov).sum() + d.dot(r.prior_precision * d) - m_ +
                       r.log_det_precision - log_det_prior);
      });
    errors.rethrow();
    for (double k : kl) elbo -= k;
    stats.elbo = elbo;
  }
  return stats;
}

}  // namespace bgkmap
