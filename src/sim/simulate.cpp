#include "bgkmap/sim/simulate.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <optional>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/core/pose_covariance.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/sim/raycaster.hpp"
#include "core/splitmix.hpp"
#include "core/stage_clock.hpp"

namespace bgkmap::sim {

namespace {
constexpr double kScanPeriodS = 0.1;  // poses.txt time stamps: a 10 Hz sensor

void prepare_scan_folder(const std::filesystem::path& scans, bool overwrite) {
  std::error_code ec;
  std::filesystem::create_directories(scans, ec);
  if (ec) throw std::runtime_error(scans.string() + ": cannot create the folder (" + ec.message() + ")");
  std::vector<std::filesystem::path> old;
  for (const auto& entry : std::filesystem::directory_iterator(scans))
    if (entry.path().extension() == ".pcd") old.push_back(entry.path());
  if (old.empty()) return;
  if (!overwrite)
    throw std::runtime_error(scans.string() + " already holds " + std::to_string(old.size()) +
                             " .pcd files: pass --overwrite to replace them, or choose another output folder");
  for (const auto& f : old) std::filesystem::remove(f);
}

// `covariances`, when given, follow each pose: 3x3 over (x, y, yaw) when `planar`, else 6x6.
void write_poses(const std::filesystem::path& file, const std::vector<Pose>& poses, const char* what,
                 const std::vector<PoseCovariance>* covariances = nullptr, bool planar = false) {
  write_file_atomically(file, [&](std::ostream& out) {
    out << "# bgkmap simulate: " << what << " sensor pose of scans/scan_N.pcd on line N (TUM format)\n"
        << "# time[s] x y z qx qy qz qw";
    if (covariances)
      out << (planar ? " and the covariance, 3x3 row-major over x y yaw (m, rad)"
                     : " and the covariance, 6x6 row-major over x y z roll pitch yaw (m, rad)");
    out << "\n";
    char line[256];
    static const int kPlanarAxes[3] = {0, 1, 5};
    for (size_t i = 0; i < poses.size(); ++i) {
      const Pose& p = poses[i];
      std::snprintf(line, sizeof line, "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g", i * kScanPeriodS, p.position.x,
                    p.position.y, p.position.z, p.qx, p.qy, p.qz, p.qw);
      out << line;
      if (covariances) {
        const PoseCovariance& c = (*covariances)[i];
        for (int r = 0; r < (planar ? 3 : 6); ++r)
          for (int k = 0; k < (planar ? 3 : 6); ++k) {
            std::snprintf(line, sizeof line, " %.17g", planar ? c(kPlanarAxes[r], kPlanarAxes[k]) : c(r, k));
            out << line;
          }
      }
      out << "\n";
    }
  });
}

// A standard normal draw of the drift's stream: scan `scan`, axis `axis` (Box-Muller on splitmix,
// apart from the sensor's streams).
double drift_normal(uint64_t seed, uint64_t scan, int axis) {
  const uint64_t h = splitmix64(splitmix64(splitmix64(seed ^ 0xD1F7D1F7D1F7D1F7ull) ^ scan) ^ uint64_t(axis));
  const double u1 = 1.0 - unit_interval(h), u2 = unit_interval(splitmix64(h));
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

// The pose error of every scan: a random walk of increments with standard deviations `drift`.
std::vector<PoseSigmaPoint> drift_errors(const PoseSigma& drift, uint64_t seed, size_t scans) {
  const double sigma[6] = {drift.xy_m, drift.xy_m, drift.z_m, drift.roll_pitch_rad, drift.roll_pitch_rad, drift.yaw_rad};
  double e[6] = {};
  std::vector<PoseSigmaPoint> errors(scans);
  for (size_t i = 0; i < scans; ++i) {
    for (int a = 0; a < 6; ++a) e[a] += sigma[a] * drift_normal(seed, i, a);
    errors[i].weight = 1;
    errors[i].translation = {e[0], e[1], e[2]};
    errors[i].rotation = {e[3], e[4], e[5]};
  }
  return errors;
}

// What the drifted estimate makes of `scan`, taken from the true pose: with the error delta =
// (t, r) the true pose is the estimate displaced by delta, so the estimate's origin is o - t and a
// point p is seen at (o - t) + Exp(r)^T (p - o).
void to_estimated_frame(const PoseSigmaPoint& error, Scan& scan) {
  const std::array<double, 9> r = rotation_matrix(error.rotation);
  const Vec3f o = scan.pose.position;
  const Vec3d t = error.translation;
  const double eo[3] = {o.x - t.x, o.y - t.y, o.z - t.z};
  for (Vec3f& p : scan.points) {
    const double d[3] = {double(p.x) - o.x, double(p.y) - o.y, double(p.z) - o.z};
    p = {static_cast<float>(eo[0] + r[0] * d[0] + r[3] * d[1] + r[6] * d[2]),
         static_cast<float>(eo[1] + r[1] * d[0] + r[4] * d[1] + r[7] * d[2]),
         static_cast<float>(eo[2] + r[2] * d[0] + r[5] * d[1] + r[8] * d[2])};  // NaN stays NaN
  }
  // Orientation: Exp(-r) q.
  const Vec3d& v = error.rotation;
  const double theta = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  const double c = std::cos(theta / 2), s = theta > 0 ? -std::sin(theta / 2) / theta : 0;
  const double aw = c, ax = s * v.x, ay = s * v.y, az = s * v.z;
  const double bw = scan.pose.qw, bx = scan.pose.qx, by = scan.pose.qy, bz = scan.pose.qz;
  scan.pose.qw = static_cast<float>(aw * bw - ax * bx - ay * by - az * bz);
  scan.pose.qx = static_cast<float>(aw * bx + ax * bw + ay * bz - az * by);
  scan.pose.qy = static_cast<float>(aw * by - ax * bz + ay * bw + az * bx);
  scan.pose.qz = static_cast<float>(aw * bz + ax * by - ay * bx + az * bw);
  scan.pose.position = {static_cast<float>(eo[0]), static_cast<float>(eo[1]), static_cast<float>(eo[2])};
}
}  // namespace

std::string scan_file_name(size_t index, size_t count) {
  const int width = std::max<int>(5, static_cast<int>(std::to_string(count > 0 ? count - 1 : 0).size()));
  char name[64];
  std::snprintf(name, sizeof name, "scan_%0*zu.pcd", width, index);
  return name;
}

double recommended_max_range(const SimulationSpec& spec) {
  const Box3d region = truth_region(spec.scene);
  const double diagonal = std::ceil(norm(region.max - region.min));
  return std::min(spec.sensor.max_range_m, diagonal);
}

std::string recommended_build_flags(const SimulationSpec& spec) {
  char flags[96];
  int n = std::snprintf(flags, sizeof flags, "--max-range %g", recommended_max_range(spec));
  // A level single-ring scanner at one height is a planar laser: without --2d its scans would make
  // a 3-D map one beam thick.
  const SensorModel& s = spec.sensor;
  if (s.kind == SensorKind::kSpinning && s.rings == 1 && s.elevation_min_deg == 0 && s.elevation_max_deg == 0) {
    const std::vector<Pose> poses = sample_poses(spec.trajectory);
    const bool level = std::all_of(poses.begin(), poses.end(), [&](const Pose& p) {
      return p.position.z == poses.front().position.z && p.qx == 0 && p.qy == 0;
    });
    if (!poses.empty() && level)
      std::snprintf(flags + n, sizeof flags - static_cast<size_t>(n), " --2d --plane-z %g", poses.front().position.z);
  }
  return flags;
}

SimulateReport simulate(const SimulationSpec& spec, const SimulateOptions& options) {
  spec.validate();
  const Box3d region = truth_region(spec.scene);
  const std::filesystem::path scans_dir = options.output_dir / "scans";
  prepare_scan_folder(scans_dir, options.overwrite);
  // scene.yaml, poses.txt and truth.bt are renamed into place together at the end; the scans are
  // renamed as each is written (on the writer thread, outside the batch).
  OutputBatch outputs;
  save_spec(options.output_dir / "scene.yaml", spec);

  const std::vector<Pose> poses = sample_poses(spec.trajectory);
  const bool drift = !options.drift.is_zero();
  const std::vector<PoseSigmaPoint> errors = drift ? drift_errors(options.drift, spec.seed, poses.size())
                                                   : std::vector<PoseSigmaPoint>{};
  if (drift) {
    std::vector<Pose> estimated;
    std::vector<PoseCovariance> covariances;
    const PoseCovariance q = PoseCovariance::from_sigma(options.drift);
    for (size_t i = 0; i < poses.size(); ++i) {
      Scan origin_only;
      origin_only.pose = poses[i];
      to_estimated_frame(errors[i], origin_only);
      estimated.push_back(origin_only.pose);
      PoseCovariance c;
      for (size_t k = 0; k < c.m.size(); ++k) c.m[k] = static_cast<double>(i + 1) * q.m[k];
      covariances.push_back(c);
    }
    const bool planar = options.drift.z_m == 0 && options.drift.roll_pitch_rad == 0;
    write_poses(options.output_dir / "poses.txt", estimated, "estimated (drifted)", &covariances, planar);
    write_poses(options.output_dir / "poses_true.txt", poses, "true");
  } else {
    write_poses(options.output_dir / "poses.txt", poses, "the");
  }

  SimulateReport report;
  const auto scan_start = Clock::now();
  const Raycaster raycaster(spec.scene);
  const std::vector<Vec3d> directions = beam_directions(spec.sensor);
  // Scan i+1 is cast while scan i is written.
  std::future<void> writing;
  for (size_t i = 0; i < poses.size(); ++i) {
    // A dynamic scene is cast as it is at the scan's time, into a raycaster of its own.
    const Scene now = spec.scene.dynamic.empty() ? Scene{} : scene_at(spec.scene, static_cast<int>(i));
    const std::optional<Raycaster> moved = spec.scene.dynamic.empty() ? std::nullopt : std::make_optional<Raycaster>(now);
    Scan scan = simulate_scan(moved ? *moved : raycaster, spec.sensor, directions, poses[i], spec.seed, i, report.counts);
    if (drift) to_estimated_frame(errors[i], scan);
    const std::filesystem::path file = scans_dir / scan_file_name(i, poses.size());
    if (writing.valid()) writing.get();  // rethrows a failed write
    writing = std::async(std::launch::async, [file, scan = std::move(scan)] { write_pcd(file, scan); });
    if (i > 0) {
      report.scan_bytes += std::filesystem::file_size(scans_dir / scan_file_name(i - 1, poses.size()));
      if (options.on_scan) options.on_scan(i, poses.size());
    }
  }
  if (writing.valid()) {
    writing.get();
    report.scan_bytes += std::filesystem::file_size(scans_dir / scan_file_name(poses.size() - 1, poses.size()));
    if (options.on_scan) options.on_scan(poses.size(), poses.size());
  }
  report.scans = poses.size();
  report.scan_seconds = seconds_since(scan_start);

  if (spec.truth_resolution_m > 0) {
    const auto truth_start = Clock::now();
    report.truth = write_truth_bt(options.output_dir / "truth.bt", scene_at(spec.scene, spec.trajectory.scans - 1),
                                  region, spec.truth_resolution_m);
    report.truth_seconds = seconds_since(truth_start);
  }
  outputs.commit();
  return report;
}

}  // namespace bgkmap::sim
