// The structure of a ROS 1 bag (format 2.0), checked before rosbag_storage reads it: that library
// trusts the offsets and lengths it finds (a garbled index offset made it read outside a chunk and
// crash), so every record, chunk and index entry is bounds-checked here first.
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>

namespace bgkmap::io_detail {

// Walks every record of the bag, decompresses every chunk (none, bz2, lz4) and checks that each
// index entry points at a message record inside its chunk and each connection id is declared.
// Returns the number of messages per topic; throws InputError naming the bag and the byte.
std::map<std::string, uint64_t> check_rosbag_structure(const std::filesystem::path& bag);

}  // namespace bgkmap::io_detail
