#!/usr/bin/env bash
# Reproduces docs/RESULTS.md's "Real data" section: the mapping methods on the two CARMEN laser
# logs of the datasets folder's carmen/ (Intel Research Lab, Freiburg building 079), scored on whole
# held-out scans (eval --holdout 0.1 --split scans --run-length 10 --seed 1: the Hilbert-maps /
# BHM protocol), and a build of the whole log per method for the cost columns and the map images.
# Writes OUT_DIR/<log>/ (maps, build reports, eval.json, renders), OUT_DIR/real_tables.md and
# docs/img/real_<log>_roc.png, docs/img/real_<log>_<method>.png (bgkl and octomap).
#
# Usage: scripts/real_data.sh [OUT_DIR]        (default OUT_DIR: out/real in the repository)
# Environment: BGKMAP (default build/bgkmap), BGKMAP_DATASETS (the datasets folder,
# datasets/locate.py: default ../shared/datasets beside the repository), IMG_DIR (default docs/img), THREADS (default 2), METHODS_intel and
# METHODS_freiburg (comma-separated; default bgkl,bgk,counting,octomap: add gpoctomap on Intel for
# another 20 minutes, 10 for its build and 10 for its held-out run, on 2 idle cores),
# GPOCTOMAP_TIMEOUT (seconds per gpoctomap run, default 1800), MEMORY_CAP (bytes of address space
# per run, default 4e9), LOGS (default "intel freiburg": which logs to run; a log missing from the
# datasets folder is named on one line and left out of the tables).
# Takes about 2 minutes on 2 cores.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/real}" && cd "${1:-$repo/out/real}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
img="${IMG_DIR:-$repo/docs/img}"
threads="${THREADS:-2}"
cap="${MEMORY_CAP:-4000000000}"
gp_timeout="${GPOCTOMAP_TIMEOUT:-1800}"
declare -A logs=([intel]=intel-corrected.log.gz [freiburg]=freiburg-079-corrected.log.gz)
declare -A method_lists=([intel]="${METHODS_intel:-bgkl,bgk,counting,octomap}"
                         [freiburg]="${METHODS_freiburg:-bgkl,bgk,counting,octomap}")
flags=(--max-range 20 --resolution 0.1 --backend cpu --threads "$threads")
tree_values=(--ot-values mean)  # the .ot renders show every cell's probability, as the .bgk ones do

[ -x "$bgkmap" ] || { echo "real_data: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }
command -v python3 >/dev/null || { echo "real_data: python3 not found (scripts/setup.sh installs it)" >&2; exit 1; }
mkdir -p "$img"

log() { echo "real_data: $*" >&2; }
map_file() { case "$1" in octomap | gpoctomap) echo "$2/$1.ot" ;; *) echo "$2/$1.bgk" ;; esac; }
limit() { case "$1" in gpoctomap) echo "$gp_timeout" ;; *) echo 600 ;; esac; }

{
  echo "$(nproc) cores, $threads threads"
  echo "load average $(cut -d' ' -f1 /proc/loadavg) before the run"
} >"$out/machine.txt"

ran=()
for name in ${LOGS:-intel freiburg}; do
  input="$(python3 "$repo/datasets/locate.py" --require "carmen/${logs[$name]}" --tag real_data)" || continue
  ran+=("$name")
  dir="$out/$name"
  mkdir -p "$dir"
  IFS=, read -r -a methods <<<"${method_lists[$name]}"
  for m in "${methods[@]}"; do
    start=$SECONDS
    timeout "$(limit "$m")" prlimit --as="$cap" -- "$bgkmap" build "$input" "${flags[@]}" "${tree_values[@]}" -q --method "$m" \
      -o "$(map_file "$m" "$dir")" --report "$dir/$m.report.json"
    "$bgkmap" render "$(map_file "$m" "$dir")" -o "$dir/$m.png" --title "${logs[$name]}: $m" 2>/dev/null
    log "$name: built $m in $((SECONDS - start)) s"
  done
  for m in bgkl octomap; do cp "$dir/$m.png" "$img/real_${name}_$m.png"; done
  timeout $((gp_timeout + 1200)) prlimit --as="$cap" -- "$bgkmap" eval --holdout 0.1 --split scans --run-length 10 \
    --seed 1 "$input" "${flags[@]}" --methods "${method_lists[$name]}" --json "$dir/eval.json" \
    --plot "$img/real_${name}_roc.png" --title "${logs[$name]}, whole held-out scans" 2>"$dir/eval.log"
  log "$name: scored"
done
[ "${#ran[@]}" -gt 0 ] || { echo "real_data: none of the logs is in the datasets folder: nothing mapped" >&2; exit 1; }
{
  echo "load average $(cut -d' ' -f1 /proc/loadavg) after it"
  echo "$(date -u +%Y-%m-%d)"
} >>"$out/machine.txt"

python3 "$repo/scripts/results_tables.py" --real "$out" "${ran[@]}" >"$out/real_tables.md"
log "tables in $out/real_tables.md, figures in $img/real_*.png"
