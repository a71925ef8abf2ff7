// The checks every binary scan reader makes before opening its file.
#pragma once

#include <cstdint>
#include <filesystem>

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

}  // namespace bgkmap::io_detail
