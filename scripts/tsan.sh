#!/usr/bin/env bash
# ThreadSanitizer on the OpenMP paths, built with clang in build-tsan/: the tests of the CPU back
# end (bucketing and the integrator, at 1 and 2 threads), of the comparison methods (gpoctomap's,
# gpom's and wgpom's, bhm's parallel loops) and of the simulator (the scanner's). GCC's libgomp is not built for TSan, so its
# barriers and work sharing are invisible and every parallel loop would read as a race; clang
# links LLVM's libomp, whose OMPT interface lets archer (libarcher.so, in libomp-14-dev)
# tell TSan about OpenMP's synchronisation. Any report fails the run (halt_on_error); reports from
# third-party code are suppressed, each with its reason, in tests/sanitizers/tsan.supp, and
# accesses inside uninstrumented libraries (libomp's own reduction buffers among them, as archer
# asks) are not checked: bgkmap's code is.
#
#   scripts/tsan.sh [TEST BINARY ARGS...]      e.g. scripts/tsan.sh --gtest_filter='Bucketing.*'
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-tsan
archer=/usr/lib/llvm-14/lib/libarcher.so
[ -f "$archer" ] || { echo "tsan.sh: $archer missing (Debian: libomp-14-dev)" >&2; exit 2; }
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
start=$(date +%s)
cmake -S . -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DBGKMAP_SANITIZE=thread -DBGKMAP_BUILD_BENCHMARKS=OFF -DBGKMAP_BUILD_PYTHON=OFF -DBGKMAP_WITH_MPI=OFF \
  "${launcher[@]}" >/dev/null
# Set before the build too: gtest_discover_tests runs each test binary when it is linked.
export OMP_TOOL_LIBRARIES="$archer" ARCHER_OPTIONS="verbose=1"
export TSAN_OPTIONS="halt_on_error=1:second_deadlock_stack=1:ignore_noninstrumented_modules=1:suppressions=$PWD/tests/sanitizers/tsan.supp"
tests=(test_bucketing test_cpu_integrator test_methods test_gpom test_bhm test_sim)
cmake --build "$build" -j2 --target "${tests[@]}"
built=$(date +%s)
rc=0
for t in "${tests[@]}"; do
  "$build/tests/$t" "$@" || rc=$?
done
echo "tsan: $(git rev-parse --short HEAD), build $(( built - start )) s, tests $(( $(date +%s) - built )) s, exit $rc"
exit $rc
