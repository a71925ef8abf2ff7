// PCD scans through PCL (ascii, binary and binary_compressed).
#pragma once

#include <filesystem>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// Reads x/y/z (other fields are ignored) and the VIEWPOINT header as the scan pose.
// Throws InputError naming the file on anything unreadable.
Scan read_pcd(const std::filesystem::path& file);

// Writes binary PCD with fields x y z and VIEWPOINT = pose, atomically.
void write_pcd(const std::filesystem::path& file, const Scan& scan);

}  // namespace bgkmap
