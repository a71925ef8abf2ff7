#include "methods/gp/uncertain_inputs.hpp"

#include <cmath>

namespace bgkmap {

PositionCovariance BeamCovariance::at(double t) const {
  const double a = (1 - t) * (1 - t), b = t * t, c = t * (1 - t);
  const std::array<double, 9>& x = cross;
  return {a * origin.xx + b * end.xx + c * 2 * x[0], a * origin.xy + b * end.xy + c * (x[1] + x[3]),
          a * origin.xz + b * end.xz + c * (x[2] + x[6]), a * origin.yy + b * end.yy + c * 2 * x[4],
          a * origin.yz + b * end.yz + c * (x[5] + x[7]), a * origin.zz + b * end.zz + c * 2 * x[8]};
}

namespace {

// sum_h w_h (a_h - mean a)(b_h - mean b)^T, row-major.
std::array<double, 9> cross_covariance(const std::vector<PoseSigmaPoint>& points, const std::vector<Vec3d>& a,
                                       const std::vector<Vec3d>& b) {
  Vec3d ma, mb;
  for (size_t h = 0; h < points.size(); ++h) {
    const double w = points[h].weight;
    ma = {ma.x + w * a[h].x, ma.y + w * a[h].y, ma.z + w * a[h].z};
    mb = {mb.x + w * b[h].x, mb.y + w * b[h].y, mb.z + w * b[h].z};
  }
  std::array<double, 9> c{};
  for (size_t h = 0; h < points.size(); ++h) {
    const double w = points[h].weight;
    const double u[3] = {a[h].x - ma.x, a[h].y - ma.y, a[h].z - ma.z}, v[3] = {b[h].x - mb.x, b[h].y - mb.y, b[h].z - mb.z};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) c[3 * i + j] += w * u[i] * v[j];
  }
  return c;
}

PositionCovariance symmetric(const std::array<double, 9>& c) { return {c[0], c[1], c[2], c[4], c[5], c[8]}; }

}  // namespace

ScanMotion::ScanMotion(const Vec3f& origin, const std::vector<PoseSigmaPoint>& points, bool planar)
    : origin_{origin.x, origin.y, origin.z}, planar_(planar) {
  for (const PoseSigmaPoint& p : points) {
    weights_.push_back(p.weight);
    translations_.push_back(p.translation);
    rotations_.push_back(rotation_matrix(p.rotation));
  }
}

void ScanMotion::displacements(const Vec3d& p, Vec3d* out) const {
  const double d[3] = {p.x - origin_.x, p.y - origin_.y, p.z - origin_.z};
  for (size_t h = 0; h < rotations_.size(); ++h) {
    const std::array<double, 9>& r = rotations_[h];
    const Vec3d& t = translations_[h];
    out[h] = {t.x + r[0] * d[0] + r[1] * d[1] + r[2] * d[2] - d[0], t.y + r[3] * d[0] + r[4] * d[1] + r[5] * d[2] - d[1],
              t.z + r[6] * d[0] + r[7] * d[1] + r[8] * d[2] - d[2]};
    if (planar_) out[h].z = 0;
  }
}

PositionCovariance across_segment(const PositionCovariance& c, const Vec3d& u) {
  // P C P with P = I - u u^T: C P = C - (C u) u^T, then P (C P) = C P - u (u^T C P).
  const double m[3][3] = {{c.xx, c.xy, c.xz}, {c.xy, c.yy, c.yz}, {c.xz, c.yz, c.zz}};
  const double v[3] = {u.x, u.y, u.z};
  double cu[3], cp[3][3], ucp[3];
  for (int i = 0; i < 3; ++i) cu[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) cp[i][j] = m[i][j] - cu[i] * v[j];
  for (int j = 0; j < 3; ++j) ucp[j] = v[0] * cp[0][j] + v[1] * cp[1][j] + v[2] * cp[2][j];
  const auto at = [&](int i, int j) { return cp[i][j] - v[i] * ucp[j]; };
  return {at(0, 0), at(0, 1), at(0, 2), at(1, 1), at(1, 2), at(2, 2)};
}

void difference_covariances(const std::vector<PositionCovariance>& marginal, const SharedMotion& shared,
                            std::vector<PositionCovariance>& out) {
  const size_t n = marginal.size(), points = shared.points;
  out.resize(n * n);
  for (size_t i = 0; i < n; ++i)
    for (size_t j = i + 1; j < n; ++j) {
      PositionCovariance c = marginal[i] + marginal[j];
      if (shared.group[i] != SharedMotion::kNoGroup && shared.group[i] == shared.group[j]) {
        double x[9] = {};  // C_ij
        for (size_t h = 0; h < points; ++h) {
          const Vec3d& a = shared.moves[i * points + h];
          const Vec3d& b = shared.moves[j * points + h];
          const double av[3] = {a.x, a.y, a.z}, bv[3] = {b.x, b.y, b.z};
          for (int r = 0; r < 3; ++r)
            for (int k = 0; k < 3; ++k) x[3 * r + k] += av[r] * bv[k];
        }
        const double w = shared.weight[i];
        c = {c.xx - 2 * w * x[0], c.xy - w * (x[1] + x[3]), c.xz - w * (x[2] + x[6]),
             c.yy - 2 * w * x[4], c.yz - w * (x[5] + x[7]), c.zz - 2 * w * x[8]};
      }
      out[i * n + j] = out[j * n + i] = c;
    }
}

PositionCovariance sensor_covariance(const Vec3f& origin, const Vec3f& end, const SensorNoise& noise, bool planar) {
  const Vec3d v{double(end.x) - origin.x, double(end.y) - origin.y, planar ? 0.0 : double(end.z) - origin.z};
  const double r = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  if (!(r > 0) || !noise.any()) return {};
  const int n = planar ? 2 : 3;
  const double spread = std::sqrt(double(n));
  const Vec3d u{v.x / r, v.y / r, v.z / r};
  // Each point's displacement of the return: along the beam, or the beam rotated about the origin
  // (2n <= 6 of them: no allocation per return).
  std::array<Vec3d, 6> moves;
  size_t count = 0;
  const auto rotated = [&](const Vec3d& rotation) {
    const std::array<double, 9> m = rotation_matrix(rotation);
    return Vec3d{m[0] * v.x + m[1] * v.y + m[2] * v.z - v.x, m[3] * v.x + m[4] * v.y + m[5] * v.z - v.y,
                 m[6] * v.x + m[7] * v.y + m[8] * v.z - v.z};
  };
  // Elevation turns the beam about the horizontal axis across it (x for a vertical beam).
  Vec3d across{-u.y, u.x, 0.0};
  const double across_norm = std::hypot(across.x, across.y);
  across = across_norm > 1e-9 ? Vec3d{across.x / across_norm, across.y / across_norm, 0.0} : Vec3d{1.0, 0.0, 0.0};
  for (const double sign : {1.0, -1.0}) {
    const double range = sign * spread * noise.range_sigma, angle = sign * spread * noise.bearing_sigma;
    moves[count++] = {range * u.x, range * u.y, range * u.z};
    moves[count++] = rotated({0.0, 0.0, angle});
    if (!planar) moves[count++] = rotated({angle * across.x, angle * across.y, 0.0});
  }
  const double w = 1.0 / double(count);
  Vec3d mean;
  for (size_t i = 0; i < count; ++i) mean = {mean.x + moves[i].x * w, mean.y + moves[i].y * w, mean.z + moves[i].z * w};
  PositionCovariance c;
  for (size_t i = 0; i < count; ++i) {
    const Vec3d d{moves[i].x - mean.x, moves[i].y - mean.y, moves[i].z - mean.z};
    c = c + PositionCovariance{w * d.x * d.x, w * d.x * d.y, w * d.x * d.z, w * d.y * d.y, w * d.y * d.z, w * d.z * d.z};
  }
  if (planar) c.xz = c.yz = c.zz = 0;
  return c;
}

void append_input_covariances(const ScanObservations& obs, const std::vector<PoseSigmaPoint>& points, bool planar,
                              const SensorNoise& sensor, std::vector<PositionCovariance>& hits,
                              std::vector<BeamCovariance>& beams) {
  if (points.empty()) {
    for (const Vec3f& hit : obs.hits) hits.push_back(sensor_covariance(obs.origin, hit, sensor, planar));
    for (const Vec3f& end : obs.free_ends) {
      BeamCovariance beam;
      beam.end = sensor_covariance(obs.origin, end, sensor, planar);
      beams.push_back(beam);
    }
    return;
  }
  const ScanMotion motion(obs.origin, points, planar);
  std::vector<Vec3d> a(motion.size()), b(motion.size());
  for (const Vec3f& hit : obs.hits) {
    motion.displacements({hit.x, hit.y, hit.z}, a.data());
    hits.push_back(symmetric(cross_covariance(points, a, a)) + sensor_covariance(obs.origin, hit, sensor, planar));
  }
  motion.displacements({obs.origin.x, obs.origin.y, obs.origin.z}, a.data());
  BeamCovariance beam;
  beam.origin = symmetric(cross_covariance(points, a, a));
  for (const Vec3f& end : obs.free_ends) {
    motion.displacements({end.x, end.y, end.z}, b.data());
    beam.end = symmetric(cross_covariance(points, b, b)) + sensor_covariance(obs.origin, end, sensor, planar);
    beam.cross = cross_covariance(points, a, b);
    beams.push_back(beam);
  }
}

}  // namespace bgkmap
