#!/usr/bin/env bash
# The distributed build's bit-identity check at the campus preset's own settings, longer than the
# ctest cases (test_mpi_build uses 4 campus scans at 20 m): the first SCANS scans of
# `bgkmap simulate campus` (0.2 m cells, l = 0.6 m, --ds 0.5, 50 m range) built by one process and
# by `mpirun --oversubscribe -np K` for K = 1..MAX_RANKS, on the CPU path and on OpenCL; every
# merged .bgk must be the single-process file byte for byte. Prints one line per build and exits
# non-zero on the first difference.
#
# Usage: scripts/mpi_identity.sh [OUT_DIR]      (default OUT_DIR: a temporary folder, removed)
# Environment: BGKMAP (default build/bgkmap), SCANS (default 30), MAX_RANKS (default 4),
# BACKENDS (default "cpu opencl"), CAMPUS (a folder of `bgkmap simulate campus`; default: simulate
# SCANS scans into OUT_DIR), MEMORY_CAP (bytes of address space per process, default 6e9).
# Takes about 5 minutes on 2 idle cores (30 scans: a 2 GB map per build).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
scans="${SCANS:-30}"
max_ranks="${MAX_RANKS:-4}"
backends="${BACKENDS:-cpu opencl}"
cap="${MEMORY_CAP:-6000000000}"
if [[ $# -ge 1 ]]; then
  out="$(mkdir -p "$1" && cd "$1" && pwd)"
else
  out="$(mktemp -d)"
  trap 'rm -rf "$out"' EXIT
fi
campus="${CAMPUS:-$out/campus}"
if [[ ! -d "$campus/scans" ]]; then
  "$bgkmap" simulate campus -q --scans "$scans" --truth-resolution 0 -o "$campus"
fi
mapfile -t inputs < <(ls "$campus"/scans/*.pcd | sort -V | head -n "$scans")
flags=(-q --resolution 0.2 --ell 0.6 --ds 0.5 --max-range 50 --threads 1)
export OMPI_MCA_btl_vader_single_copy_mechanism=none OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

for backend in $backends; do
  single="$out/single-$backend.bgk"
  (ulimit -v $((cap / 1024)); "$bgkmap" build "${inputs[@]}" "${flags[@]}" --backend "$backend" -o "$single")
  expected="$(sha256sum < "$single" | cut -c1-64)"
  echo "mpi_identity: $scans campus scans, $backend, 1 process: $expected ($(stat -c %s "$single") bytes)"
  for ((k = 1; k <= max_ranks; ++k)); do
    merged="$out/k$k-$backend.bgk"
    (ulimit -v $((cap / 1024)); mpirun --oversubscribe -np "$k" "$bgkmap" build "${inputs[@]}" "${flags[@]}" \
      --backend "$backend" -o "$merged" --shards "$out/k$k-$backend.shards")
    got="$(sha256sum < "$merged" | cut -c1-64)"
    echo "mpi_identity: $scans campus scans, $backend, $k ranks: $got"
    if [[ "$got" != "$expected" ]]; then
      echo "mpi_identity: $k ranks on $backend differ from the single-process map" >&2
      exit 1
    fi
    rm -rf "$merged" "$out/k$k-$backend.shards"
  done
  rm -f "$single"
done
echo "mpi_identity: every merged map is the single-process map"
