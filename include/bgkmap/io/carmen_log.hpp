// CARMEN laser logs (.log, .clf, .gfs.log, and the same gzipped): one planar scan per laser
// message, read a line at a time (gzipped logs are decompressed in memory as they are read).
//
// Messages that give scans (fields whitespace separated, one message per line):
//   FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta ipc_timestamp ipc_hostname [logger_timestamp]
//   RLASER  (the same fields, the rear laser)
//   ROBOTLASER1 laser_type start_angle fov angular_res max_range accuracy remission_mode
//               n r_1 .. r_n m v_1 .. v_m x y theta robot_x robot_y robot_theta tv rv
//               forward_safety side_safety turn_axis ipc_timestamp ipc_hostname [logger_timestamp]
// x y theta is the laser's corrected pose in the world (metres, radians). Scans are planar at
// z = 0: world-frame points (x + r cos a_i, y + r sin a_i, 0) and origin (x, y, 0), orientation
// the yaw theta.
//
// Beam angles. FLASER/RLASER carry none: beam i of n points at a_i = theta - 90 deg +
// i * 180 deg / n, the convention of the Hilbert-maps evaluation code (and of the shared
// datasets' README). Some readers use 180 deg / (n - 1), so that the last beam points at
// +90 deg; for the 180-beam Intel log the two differ by at most one degree at the last beam
// (i / (n (n - 1)) of 180 deg). ROBOTLASER1 gives them: a_i = theta + start_angle + i * angular_res.
//
// No return. A SICK laser that sees nothing reports a code at its maximum (81.83 m in the Intel
// log, 81.91 m in FR-079); a FLASER/RLASER reading at or beyond kCarmenNoReturnRangeM, or a
// ROBOTLASER1 reading at or beyond the message's max_range, is such a "no return". The reader
// keeps the point (along its beam, at the reading) and sets Scan::no_return_range_m, so that
// preprocessing never makes it a hit: with --max-range it is a beam beyond the max range
// (a free beam of max-range length, or dropped with --beyond-range drop), without one it is
// dropped and counted (its free length is not known). A reading of 0 or less (no measurement)
// or NaN/Inf becomes a NaN point, dropped and counted by preprocessing.
//
// Other messages (ODOM, PARAM, NEFF, SYNC, TRUEPOS, ...) and '#' comment lines carry no scans:
// they are skipped and counted by type. A malformed laser line (a field that is not a number, a
// count that disagrees with the number of fields, a non-finite pose) or a truncated or corrupt
// gzip stream throws InputError naming the file and the line.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// FLASER/RLASER readings at or beyond this are a SICK laser's "no return" codes (81.83, 81.91
// m): SICK LMS 2xx lasers measure up to 80 m at most.
constexpr float kCarmenNoReturnRangeM = 81.0f;

// True for a file name the CARMEN reader takes: *.log, *.clf, and the same with .gz
// (case-insensitive; .gfs.log ends in .log).
bool is_carmen_log_name(const std::filesystem::path& file);

class CarmenLogReader {
 public:
  // Opens the file; throws InputError naming it when it cannot be opened.
  explicit CarmenLogReader(const std::filesystem::path& file);
  ~CarmenLogReader();
  CarmenLogReader(CarmenLogReader&&) noexcept;
  CarmenLogReader& operator=(CarmenLogReader&&) noexcept;

  // The next laser message as a scan; false after the last line. Throws InputError as above.
  bool next(Scan& scan);

  // Messages skipped so far, by type (first field); comment lines are not counted.
  const std::map<std::string, uint64_t>& skipped_messages() const;

  // The share of the log read so far, 0 to 1 (of its uncompressed bytes when gzipped).
  double fraction_read() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace bgkmap
