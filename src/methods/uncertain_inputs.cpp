#include "methods/uncertain_inputs.hpp"

namespace bgkmap {

PositionCovariance BeamCovariance::at(double t) const {
  const double a = (1 - t) * (1 - t), b = t * t, c = t * (1 - t);
  const std::array<double, 9>& x = cross;
  return {a * origin.xx + b * end.xx + c * 2 * x[0], a * origin.xy + b * end.xy + c * (x[1] + x[3]),
          a * origin.xz + b * end.xz + c * (x[2] + x[6]), a * origin.yy + b * end.yy + c * 2 * x[4],
          a * origin.yz + b * end.yz + c * (x[5] + x[7]), a * origin.zz + b * end.zz + c * 2 * x[8]};
}

namespace {

// Each sigma point's displacement of p: t + (R - I)(p - o) (z dropped on a planar map).
struct Displacements {
  std::vector<std::array<double, 9>> rotations;
  const std::vector<PoseSigmaPoint>* points;
  Vec3d origin;
  bool planar;

  void of(const Vec3f& p, std::vector<Vec3d>& out) const {
    out.resize(rotations.size());
    const double d[3] = {p.x - origin.x, p.y - origin.y, p.z - origin.z};
    for (size_t h = 0; h < rotations.size(); ++h) {
      const std::array<double, 9>& r = rotations[h];
      const Vec3d& t = (*points)[h].translation;
      out[h] = {t.x + r[0] * d[0] + r[1] * d[1] + r[2] * d[2] - d[0], t.y + r[3] * d[0] + r[4] * d[1] + r[5] * d[2] - d[1],
                t.z + r[6] * d[0] + r[7] * d[1] + r[8] * d[2] - d[2]};
      if (planar) out[h].z = 0;
    }
  }
};

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

void append_input_covariances(const ScanObservations& obs, const std::vector<PoseSigmaPoint>& points, bool planar,
                              std::vector<PositionCovariance>& hits, std::vector<BeamCovariance>& beams) {
  if (points.empty()) {
    hits.resize(hits.size() + obs.hits.size());
    beams.resize(beams.size() + obs.free_ends.size());
    return;
  }
  Displacements moves{{}, &points, {obs.origin.x, obs.origin.y, obs.origin.z}, planar};
  for (const PoseSigmaPoint& p : points) moves.rotations.push_back(rotation_matrix(p.rotation));
  std::vector<Vec3d> a, b;
  for (const Vec3f& hit : obs.hits) {
    moves.of(hit, a);
    hits.push_back(symmetric(cross_covariance(points, a, a)));
  }
  moves.of(obs.origin, a);
  BeamCovariance beam;
  beam.origin = symmetric(cross_covariance(points, a, a));
  for (const Vec3f& end : obs.free_ends) {
    moves.of(end, b);
    beam.end = symmetric(cross_covariance(points, b, b));
    beam.cross = cross_covariance(points, a, b);
    beams.push_back(beam);
  }
}

}  // namespace bgkmap
