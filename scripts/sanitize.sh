#!/usr/bin/env bash
# The whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer (with LeakSanitizer),
# built with clang in build-asan/ (GCC's UBSan instrumentation made the build several times
# slower), the tree scripts/fuzz.sh builds its targets in (-DBGKMAP_FUZZ=ON: the sanitizers plus
# libFuzzer's coverage, so one instrumented build serves both). Any report fails the test that triggered it
# (-fno-sanitize-recover=all, halt_on_error). Leaks that third-party libraries keep for the life of
# the process are suppressed, each with its reason, in tests/sanitizers/lsan.supp. The Python
# module is left out: an instrumented extension needs the ASan runtime loaded before the
# interpreter, and the library code it wraps is what the C++ tests run. A process past 3 GB
# resident is stopped as a finding (hard_rss_limit_mb). Prints the build and suite times.
#
#   scripts/sanitize.sh [CTEST ARGS...]      e.g. scripts/sanitize.sh -R Bucketing
#   SANITIZE_TARGETS="test_scan_io test_map_io" scripts/sanitize.sh -R 'ScanIo|MapIo'
#                                            builds only those targets (run the tests they hold)
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-asan
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
start=$(date +%s)
cmake -S . -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBGKMAP_FUZZ=ON \
  -DBGKMAP_BUILD_BENCHMARKS=OFF -DBGKMAP_BUILD_PYTHON=OFF "${launcher[@]}" >/dev/null
# Set before the build too: gtest_discover_tests runs each test binary when it is linked.
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:hard_rss_limit_mb=3000"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizers/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
targets=()
[ -n "${SANITIZE_TARGETS:-}" ] && read -r -a targets <<<"--target $SANITIZE_TARGETS"
cmake --build "$build" -j2 "${targets[@]}"
built=$(date +%s)
mpi='(^|/)MpiBuild(Faults)?[.]'
rc=0
ctest --test-dir "$build" --output-on-failure -j2 -E "$mpi" "$@" || rc=$?
# Open MPI unloads its components (mca_*.so) at MPI_Finalize, so what they keep allocated shows up
# as leaks from "<unknown module>" that no suppression can name: the distributed build's tests
# (mpirun and its ranks) run with leak detection off; ASan's other checks and UBSan stay on.
ASAN_OPTIONS="$ASAN_OPTIONS:detect_leaks=0" ctest --test-dir "$build" --output-on-failure -j2 -R "$mpi" "$@" || rc=$?
echo "sanitize: $(git rev-parse --short HEAD), build $(( built - start )) s, suite $(( $(date +%s) - built )) s, ctest exit $rc"
exit $rc
