// Passive waiting of OpenMP threads for the bgkmap commands that run parallel work.
//
// By default libgomp lets a thread with nothing to do spin for up to about 3 ms before it
// sleeps. With another process busy on one of the cores, the team thread that shares that core
// spins away its share of it, is preempted while it holds work, and every parallel region waits
// for it: on 2 cores with one busy, sim_structured's insert took 3 s on 2 threads instead of
// 0.04 s (docs/BENCHMARKS.md). With passive waiting (sleep at once) 2 threads stay no slower
// than 1 there. libgomp reads OMP_WAIT_POLICY in its constructor, before main(), and the C
// library resets the environment after .preinit_array, so the only portable way to set it is
// to start the program again with it set: that costs one more program start (a few tens of ms).
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
