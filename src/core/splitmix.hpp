// splitmix64: the counter-based hash behind every reproducible random draw of the library (held-out
// splits, simulated sensor noise, preset scenes): explicit arithmetic, so the same seed gives the
// same numbers on every platform and compiler (unlike the standard library's distributions).
#pragma once

#include <cstdint>

namespace bgkmap {

inline constexpr uint64_t kSplitmixIncrement = 0x9E3779B97F4A7C15ull;

// The value splitmix64 yields for state x (the state advances by kSplitmixIncrement per draw).
inline uint64_t splitmix64(uint64_t x) {
  x += kSplitmixIncrement;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

// The top 53 bits of a hash as a double in [0, 1).
inline double unit_interval(uint64_t h) { return static_cast<double>(h >> 11) * 0x1.0p-53; }

}  // namespace bgkmap
