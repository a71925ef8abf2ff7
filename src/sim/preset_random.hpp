// The presets' random numbers: splitmix64 and explicit arithmetic, unlike the standard library's
// distributions (whose output is implementation-defined), so a preset is the same scene on
// every platform and compiler.
#pragma once

#include <cstdint>

#include "core/splitmix.hpp"

namespace bgkmap::sim {

class PresetRandom {
 public:
  explicit PresetRandom(uint64_t seed) : state_(seed) {}
  double uniform(double lo, double hi) { return lo + (hi - lo) * unit(); }
  int integer(int lo, int hi) { return lo + static_cast<int>(unit() * (hi - lo + 1)); }  // [lo, hi]
  bool chance(double p) { return unit() < p; }

 private:
  double unit() {  // [0, 1)
    const uint64_t z = splitmix64(state_);
    state_ += kSplitmixIncrement;
    return unit_interval(z);
  }
  uint64_t state_;
};

}  // namespace bgkmap::sim
