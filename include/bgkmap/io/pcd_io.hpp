// PCD scans: read through PCL (ascii, binary and binary_compressed), written as binary PCD.
#pragma once

#include <filesystem>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// Reads x/y/z as stored (other fields are ignored; NaN/Inf points are kept for preprocessing to
// drop and count) and the VIEWPOINT header as the scan pose: origin = its translation,
// orientation = its quaternion, normalised. A missing VIEWPOINT, or exactly PCL's default
// "0 0 0 1 0 0 0", is no pose (Scan::has_own_pose false: ScanSource wants --origin or --poses).
// The points are not transformed here: they are taken to be world-frame unless
// PreprocessParams::apply_viewpoint (--frame sensor) says they are sensor-frame.
// The file is checked before PCL decodes it (PCL trusts its header counts), so a truncated or
// corrupt file throws InputError naming it ("scan.pcd: PCD: truncated binary data ...") instead
// of crashing or allocating what its header claims.
Scan read_pcd(const std::filesystem::path& file);

// Whether the file's header gives a sensor pose (a VIEWPOINT other than PCL's default), read from
// the header alone; throws InputError naming the file when the header cannot be read.
bool pcd_has_viewpoint(const std::filesystem::path& file);

// Writes binary PCD with fields x y z and VIEWPOINT = pose (shortest exact float text, so
// read_pcd gives back the same floats), atomically. A scan without a pose of its own gets PCL's
// default VIEWPOINT; one at the origin unturned gets "0 0 0 -1 0 0 0", the same pose, so that it
// reads back as a pose given. Throws std::runtime_error naming the file
// when it cannot be written or the pose is not finite.
void write_pcd(const std::filesystem::path& file, const Scan& scan);

}  // namespace bgkmap
