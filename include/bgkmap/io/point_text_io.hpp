// Scans without a sensor pose of their own: plain XYZ text (`.xyz`) and PLY (`.ply`, ascii and
// binary, through PCL's reader); io/pose_list.hpp reads the poses file that gives them one.
#pragma once

#include <filesystem>
#include <vector>

#include "bgkmap/core/scan.hpp"

namespace bgkmap {

// XYZ text: one point a line, "x y z" and optionally more columns (ignored); blank lines and
// lines starting with '#' or '//' skipped. The file may be gzipped (.xyz.gz). NaN/Inf kept (for
// preprocessing to drop and count). Returns the points with an identity pose. Throws InputError
// naming the file and the line for a line without three numbers.
Scan read_xyz(const std::filesystem::path& file);

// PLY (ascii, binary_little_endian, binary_big_endian): the x, y, z properties (float or double)
// of the "vertex" element; other elements and properties are ignored. The header is checked
// before PCL decodes the body (PCL trusts the counts): a count the file cannot hold, a missing
// x/y/z, a truncated body or bad ascii data is an InputError naming the file. Identity pose.
Scan read_ply(const std::filesystem::path& file);

}  // namespace bgkmap
