#!/usr/bin/env bash
# The whole test suite under AddressSanitizer + UndefinedBehaviorSanitizer (with LeakSanitizer),
# built in build-asan/. Any report fails the test that triggered it (-fno-sanitize-recover).
# Leaks kept by PoCL and fontconfig for the life of the process are suppressed
# (tests/sanitizers/lsan.supp). Prints the build and suite times.
#
#   scripts/sanitize.sh [CTEST ARGS...]      e.g. scripts/sanitize.sh -R Bucketing
set -euo pipefail
cd "$(dirname "$0")/.."
build=build-asan
start=$(date +%s)
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBGKMAP_SANITIZE=address,undefined \
  -DBGKMAP_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$build" -j2
built=$(date +%s)
export ASAN_OPTIONS="detect_leaks=1:abort_on_error=1:detect_odr_violation=0"
export LSAN_OPTIONS="suppressions=$PWD/tests/sanitizers/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
rc=0
ctest --test-dir "$build" --output-on-failure -j2 "$@" || rc=$?
echo "sanitize: build $(( built - start )) s, suite $(( $(date +%s) - built )) s, ctest exit $rc"
exit $rc
