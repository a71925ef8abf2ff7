#include "bgkmap/sim/simulate.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <future>
#include <stdexcept>
#include <system_error>
#include <vector>

#include "bgkmap/io/atomic_file.hpp"
#include "bgkmap/io/pcd_io.hpp"
#include "bgkmap/sim/raycaster.hpp"
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

void write_poses(const std::filesystem::path& file, const std::vector<Pose>& poses) {
  write_file_atomically(file, [&](std::ostream& out) {
    out << "# bgkmap simulate: sensor pose of scans/scan_N.pcd on line N (TUM format)\n"
        << "# time[s] x y z qx qy qz qw\n";
    char line[256];
    for (size_t i = 0; i < poses.size(); ++i) {
      const Pose& p = poses[i];
      std::snprintf(line, sizeof line, "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g\n", i * kScanPeriodS, p.position.x,
                    p.position.y, p.position.z, p.qx, p.qy, p.qz, p.qw);
      out << line;
    }
  });
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
  char flags[64];
  std::snprintf(flags, sizeof flags, "--max-range %g", recommended_max_range(spec));
  return flags;
}

SimulateReport simulate(const SimulationSpec& spec, const SimulateOptions& options) {
  spec.validate();
  const Box3d region = truth_region(spec.scene);
  const std::filesystem::path scans_dir = options.output_dir / "scans";
  prepare_scan_folder(scans_dir, options.overwrite);
  save_spec(options.output_dir / "scene.yaml", spec);

  const std::vector<Pose> poses = sample_poses(spec.trajectory);
  write_poses(options.output_dir / "poses.txt", poses);

  SimulateReport report;
  const auto scan_start = Clock::now();
  const Raycaster raycaster(spec.scene);
  const std::vector<Vec3d> directions = beam_directions(spec.sensor);
  // Scan i+1 is cast while scan i is written.
  std::future<void> writing;
  for (size_t i = 0; i < poses.size(); ++i) {
    Scan scan = simulate_scan(raycaster, spec.sensor, directions, poses[i], spec.seed, i, report.counts);
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
    report.truth = write_truth_bt(options.output_dir / "truth.bt", spec.scene, region, spec.truth_resolution_m);
    report.truth_seconds = seconds_since(truth_start);
  }
  return report;
}

}  // namespace bgkmap::sim
