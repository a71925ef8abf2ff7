// The datasets folder for the C++ tests and benchmarks, by datasets/locate.py's rule.
#pragma once

#include <cstdlib>
#include <filesystem>

namespace bgkmap::datasets {

// $BGKMAP_DATASETS when set and not empty, else the build's default (CMake BGKMAP_DATASETS_DIR,
// which is ../shared/datasets beside the checkout unless configured otherwise).
inline std::filesystem::path datasets_dir(const char* build_default) {
  if (const char* env = std::getenv("BGKMAP_DATASETS"); env && *env) return env;
  return build_default;
}

}  // namespace bgkmap::datasets
