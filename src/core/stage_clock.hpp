// The clock that every stage timing of the build report (read_s, insert_s and its parts) reads.
#pragma once

#include <chrono>

namespace bgkmap {

using Clock = std::chrono::steady_clock;

inline double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace bgkmap
