// Whether a method's scans are planar (2-D) or 3-D, for the methods that map planar scans in
// their plane (gpom, bhm). Internal header.
#pragma once

#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "bgkmap/core/grid.hpp"

namespace bgkmap {

// A scan is planar when every point lies within kTolerance_m of its origin's z. The first scan
// with points decides; a later scan of the other kind, or planar at another height, is refused.
class ScanPlane {
 public:
  static constexpr double kTolerance_m = 1e-6;

  // Throws std::invalid_argument naming the method and the scan (1-based) on a mix.
  void check(const std::string& method, uint64_t scan_number, const Vec3f& origin, const std::vector<Vec3f>& points) {
    if (points.empty()) return;
    const double z = origin.z;
    bool planar = true;
    for (const Vec3f& p : points) planar = planar && std::abs(p.z - z) <= kTolerance_m;
    if (!known_) {
      known_ = true;
      planar_ = planar;
      z_ = z;
      return;
    }
    if (planar != planar_ || (planar && std::abs(z - z_) > kTolerance_m))
      throw std::invalid_argument(
          method + ": scan " + std::to_string(scan_number) +
          (planar ? " is planar at z = " + std::to_string(z) : " is 3-D") + " but the scans before it are " +
          (planar_ ? "planar at z = " + std::to_string(z_) : "3-D") +
          "; 2-D and 3-D scans (or planes at different heights) cannot be mixed");
  }

  bool known() const { return known_; }
  bool planar() const { return planar_; }
  double z() const { return z_; }  // the plane's height (planar scans)

 private:
  bool known_ = false, planar_ = false;
  double z_ = 0;
};

}  // namespace bgkmap
