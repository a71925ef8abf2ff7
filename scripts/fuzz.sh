#!/usr/bin/env bash
# Builds the libFuzzer targets (fuzz/, clang, ASan + UBSan) in build-asan/ (the tree
# scripts/sanitize.sh runs the suite in; fuzz_config_yaml needs the whole library built there, the
# readers' targets only their subset) and runs each for
# SECONDS (default 60), one after another, niced. Seeds come from scripts/fuzz_seeds.py (the
# project's own simulate/build output); each target's corpus grows in build-asan/corpus/TARGET and
# what it finds lands in build-asan/artifacts/. Prints executions per target; exit 1 on a finding.
#
#   scripts/fuzz.sh [SECONDS] [TARGET...]      e.g. scripts/fuzz.sh 600 fuzz_pcd
#   FUZZ_RUNS=1000000 scripts/fuzz.sh 900     each target stops at 10^6 executions or 900 s
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
all=(fuzz_pcd fuzz_scan_graph fuzz_native_map fuzz_octree_ot fuzz_octree_bt fuzz_scene_yaml fuzz_carmen_log
     fuzz_octomap_log fuzz_ply fuzz_xyz fuzz_kitti fuzz_rosbag fuzz_config_yaml)
[ $# -gt 0 ] && targets=("$@") || targets=("${all[@]}")
build=build-asan

# The seed kind each target starts from, and the longest input it is given (the seeds are a few
# hundred bytes to 2.4 KiB; longer inputs only slow each run down).
declare -A kind=([fuzz_pcd]=pcd [fuzz_scan_graph]=graph [fuzz_native_map]=bgk [fuzz_octree_ot]=ot
                 [fuzz_octree_bt]=bt [fuzz_scene_yaml]=scene [fuzz_carmen_log]=carmen
                 [fuzz_octomap_log]=octomap_log [fuzz_ply]=ply [fuzz_xyz]=xyz [fuzz_kitti]=kitti [fuzz_rosbag]=rosbag
                 [fuzz_config_yaml]=config)
declare -A max_len=([fuzz_pcd]=4096 [fuzz_scan_graph]=4096 [fuzz_native_map]=4096 [fuzz_octree_ot]=2048
                    [fuzz_octree_bt]=2048 [fuzz_scene_yaml]=4096 [fuzz_carmen_log]=4096
                    [fuzz_octomap_log]=4096 [fuzz_ply]=4096 [fuzz_xyz]=2048 [fuzz_kitti]=1024
                    [fuzz_rosbag]=4096 [fuzz_config_yaml]=2048)

launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
cmake -S . -B "$build" -DCMAKE_CXX_COMPILER=clang++-14 -DCMAKE_BUILD_TYPE=RelWithDebInfo -DBGKMAP_FUZZ=ON \
  -DBGKMAP_BUILD_BENCHMARKS=OFF -DBGKMAP_BUILD_PYTHON=OFF "${launcher[@]}" >/dev/null
nice cmake --build "$build" -j2 --target "${targets[@]}"

# Seeds from an uninstrumented bgkmap (the normal build's, built if missing).
if [ ! -d "$build/seeds" ]; then
  [ -x build/bgkmap ] || { cmake -S . -B build >/dev/null && nice cmake --build build -j2 --target bgkmap_cli; }
  python3 scripts/fuzz_seeds.py build/bgkmap "$build/seeds.tmp" && mv "$build/seeds.tmp" "$build/seeds"
fi

export ASAN_OPTIONS="${ASAN_OPTIONS:-detect_leaks=1}"
export UBSAN_OPTIONS="${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}"
mkdir -p "$build/artifacts" "$build/logs"
status=0
printf '%-18s %12s %8s %s\n' target executions seconds result
for t in "${targets[@]}"; do
  corpus="$build/corpus/$t"
  mkdir -p "$corpus"
  log="$build/logs/$t.log"
  rc=0
  began=$(date +%s)
  # -timeout: a run over 10 s is a hang; -rss_limit_mb: runaway memory is a finding too.
  nice "$build/fuzz/$t" -max_total_time="$seconds" -max_len="${max_len[$t]}" -timeout=10 -rss_limit_mb=2048 \
    -runs="${FUZZ_RUNS:--1}" \
    -print_final_stats=1 -artifact_prefix="$build/artifacts/$t-" "$corpus" "$build/seeds/${kind[$t]}" \
    >"$log" 2>&1 || rc=$?
  secs=$(( $(date +%s) - began ))
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  result=ok
  [ "$rc" -ne 0 ] && { result="FINDING (exit $rc, see $log)"; status=1; }
  printf '%-18s %12s %8s %s\n' "$t" "${runs:-?}" "$secs" "$result"
done
exit $status
