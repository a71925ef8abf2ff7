// Passive waiting of OpenMP threads for the bgkmap commands that run parallel work.
//
// Idle threads spinning beside a busy core make every parallel region wait (docs/BENCHMARKS.md).
// libgomp reads OMP_WAIT_POLICY before main() and the C library resets the environment after
// .preinit_array, so the only portable way to set it is to start the program again with it set.
#include "cli/omp_wait_policy.hpp"

#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <string>

namespace bgkmap::cli {

void restart_with_passive_waiting(int argc, char** argv) {
  if (argc < 2) return;
  const std::string command = argv[1];
  if (command != "build" && command != "simulate" && command != "station-keeping" && command != "tune") return;
  if (std::getenv("OMP_WAIT_POLICY") != nullptr || std::getenv("GOMP_SPINCOUNT") != nullptr) return;
  if (setenv("OMP_WAIT_POLICY", "passive", 1) != 0) return;
  execv("/proc/self/exe", argv);
  unsetenv("OMP_WAIT_POLICY");  // the restart failed: go on as the user started it
}

const char* omp_wait_policy() {
  static std::string policy;
  if (const char* p = std::getenv("OMP_WAIT_POLICY")) policy = p;
  else if (const char* s = std::getenv("GOMP_SPINCOUNT")) policy = std::string("spin ") + s;
  else policy = "runtime default";
  return policy.c_str();
}

}  // namespace bgkmap::cli
