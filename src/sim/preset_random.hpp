// The presets' random numbers: splitmix64 and explicit arithmetic, unlike the standard library's
// distributions (whose output is implementation-defined), so a preset is the same scene on
// every platform and compiler.
#pragma once

#include <cstdint>

namespace bgkmap::sim {

class PresetRandom {
 public:
  explicit PresetRandom(uint64_t seed) : state_(seed) {}
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  int integer(int lo, int hi) { return lo + static_cast<int>(unit() * (hi - lo + 1)); }  // [lo, hi]
  bool chance(double p) { return unit() < p; }

 private:
  double unit() {  // [0, 1)
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * 0x1.0p-53;
  }
  uint64_t state_;
};

}  // namespace bgkmap::sim
