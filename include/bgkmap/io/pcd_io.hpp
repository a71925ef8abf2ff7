// PCD scans: read through PCL (ascii, binary and binary_compressed), written as binary PCD.
#pragma once

#include <filesystem>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// Reads x/y/z as stored (other fields are ignored; NaN/Inf points are kept for preprocessing to
// drop and count) and the VIEWPOINT header as the scan pose: origin = its translation,
// orientation = its quaternion, normalised. The points are not transformed here: they are taken
// to be world-frame unless PreprocessParams::apply_viewpoint says they are sensor-frame.
// The file is checked before PCL decodes it (PCL trusts its header counts), so a truncated or
// corrupt file throws InputError naming it ("scan.pcd: PCD: truncated binary data ...") instead
// of crashing or allocating what its header claims.
Scan read_pcd(const std::filesystem::path& file);

// Writes binary PCD with fields x y z and VIEWPOINT = pose (shortest exact float text, so
// read_pcd gives back the same floats), atomically. Throws std::runtime_error naming the file
// when it cannot be written or the pose is not finite.
void write_pcd(const std::filesystem::path& file, const Scan& scan);

}  // namespace bgkmap
