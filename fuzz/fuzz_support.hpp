// What every fuzz target shares: the fuzzer's bytes as a file (the readers take paths, as the
// command line gives them), and the contract each reader must keep on any bytes: return, or
// throw InputError naming the file. Anything else (another exception, a crash, a sanitizer
// report, a leak, a hang) is a finding.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>

#include "bgkmap/core/scan.hpp"

namespace bgkmap::fuzz {

// This process's scratch path with the given extension (in /dev/shm where there is one).
std::filesystem::path scratch_path(const char* extension);

// Writes `data` to this process's scratch file (in /dev/shm where there is one) with the given
// extension and returns its path; the same path each call, so the file is overwritten.
std::filesystem::path write_input(const uint8_t* data, size_t size, const char* extension);

// Runs `read`; InputError is the clean refusal. Any other exception aborts with its message,
// so libFuzzer records the input.
void expect_clean(const std::function<void()>& read);

// Opens `source` with a scan reader (constructor from a path, bool next(Scan&)) and reads every
// scan it gives.
template <typename Reader>
void read_every_scan(const std::filesystem::path& source) {
  Reader reader(source);
  Scan scan;
  while (reader.next(scan)) {
  }
}

}  // namespace bgkmap::fuzz
