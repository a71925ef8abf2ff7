// The checks every binary scan reader makes before opening its file.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "bgkmap/core/memory_limit.hpp"
#include "bgkmap/io/errors.hpp"

namespace bgkmap::io_detail {

// The size of an existing regular file; InputError naming it otherwise.
inline uint64_t input_file_size(const std::filesystem::path& file) {
  std::error_code ec;
  const std::filesystem::file_status status = std::filesystem::status(file, ec);
  if (!std::filesystem::exists(status)) throw InputError(file, "no such file");
  if (!std::filesystem::is_regular_file(status)) throw InputError(file, "not a regular file");
  const uint64_t size = std::filesystem::file_size(file, ec);
  if (ec) throw InputError(file, "cannot read (" + ec.message() + ")");
  return size;
}

// Before a reader allocates for the `points` its header (or size) promises, `bytes_per_point`
// each: MemoryLimitExceeded naming the file unless they fit --max-memory (a sparse file can
// promise 10^8 points in a few bytes on disk). `items`: what the points are ("blocks").
inline void require_read_memory(const std::filesystem::path& file, uint64_t points, double bytes_per_point,
                                const char* items = "points") {
  constexpr double kSmallReadBytes = 16 << 20;  // below, the mapping steps' own checks decide
  if (double(points) * bytes_per_point < kSmallReadBytes) return;
  require_memory(double(points) * bytes_per_point,
                 "reading " + file.string() + " (" + std::to_string(points) + " " + items + ")", "raise --max-memory");
}

}  // namespace bgkmap::io_detail
