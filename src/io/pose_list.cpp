#include "bgkmap/io/pose_list.hpp"

#include <array>
#include <cmath>
#include <string>

#include "text_lines.hpp"

namespace bgkmap {

using io_detail::parse_number;
using io_detail::split_fields;
using io_detail::TextLines;

std::vector<PoseRecord> read_pose_list(const std::filesystem::path& file) {
  TextLines lines(file);
  std::vector<PoseRecord> poses;
  std::string line;
  while (lines.next(line)) {
    const auto f = split_fields(line);
    if (f.empty() || f[0].front() == '#') continue;
    if (f.size() != 8 && f.size() != 17 && f.size() != 44)
      lines.fail("poses: " + std::to_string(f.size()) +
                 " fields, expected time x y z qx qy qz qw, then optionally a 3x3 (9 numbers) or 6x6 (36) covariance");
    std::vector<double> v(f.size());
    for (size_t i = 0; i < f.size(); ++i)
      if (!parse_number(f[i], v[i]) || !std::isfinite(v[i]))
        lines.fail("poses: field " + std::to_string(i + 1) + " is not a finite number");
    const double norm = std::sqrt(v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]);
    if (!(norm > 1e-6)) lines.fail("poses: zero quaternion");
    PoseRecord r;
    r.line = lines.line_number();
    r.pose.position = {static_cast<float>(v[1]), static_cast<float>(v[2]), static_cast<float>(v[3])};
    r.pose.qx = static_cast<float>(v[4] / norm);
    r.pose.qy = static_cast<float>(v[5] / norm);
    r.pose.qz = static_cast<float>(v[6] / norm);
    r.pose.qw = static_cast<float>(v[7] / norm);
    if (f.size() == 17) {
      std::array<double, 9> planar{};
      for (size_t i = 0; i < 9; ++i) planar[i] = v[8 + i];
      r.covariance = PoseCovariance::from_planar(planar);
    } else if (f.size() == 44) {
      r.covariance = PoseCovariance{};
      for (size_t i = 0; i < 36; ++i) r.covariance->m[i] = v[8 + i];
    }
    if (r.covariance) {
      const std::string problem = pose_covariance_problem(*r.covariance);
      if (!problem.empty()) lines.fail("poses: the covariance is " + problem);
    }
    poses.push_back(r);
  }
  return poses;
}

}  // namespace bgkmap
