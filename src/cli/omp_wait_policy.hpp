// The bgkmap command makes OpenMP threads wait passively unless the user chose (see the .cpp).
#pragma once

namespace bgkmap::cli {

// For the commands that run OpenMP work (build, simulate, station-keeping, tune): when the user set
// neither OMP_WAIT_POLICY nor GOMP_SPINCOUNT, sets OMP_WAIT_POLICY=passive and starts this
// program again with the same arguments (the runtime reads its settings before main). Returns
// only when there is nothing to do or the restart failed.
void restart_with_passive_waiting(int argc, char** argv);

// The OpenMP wait policy this process runs with, for the report: "passive", "active", or
// "spin N" for a GOMP_SPINCOUNT, or "runtime default".
const char* omp_wait_policy();

}  // namespace bgkmap::cli
