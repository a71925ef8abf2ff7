#!/usr/bin/env bash
# Reproduces docs/RESULTS.md's comparison of the five mapping methods (bgkl, bgk, counting,
# octomap, gpoctomap):
#   - the simulator's structured and unstructured presets: each method built on the same scans
#     (--ds 0.1 --max-range 14, CPU back end), all five maps scored together against scene.yaml;
#   - the datasets folder's sim_structured with la3dm's settings: the held-out protocol (10 % of
#     each scan's beams, seed 1) per method, and a build of all scans per method for the cost
#     columns; when it is missing, one line says so and the presets' tables are made alone.
# Writes OUT_DIR/<dataset>/ (scans, maps, build reports, eval.json), OUT_DIR/tables.md (the
# markdown tables of docs/RESULTS.md) and docs/img/results_<dataset>_roc.png (ROC and PR overlaid).
#
# Usage: scripts/results.sh [OUT_DIR]          (default OUT_DIR: out/results in the repository)
# Environment: BGKMAP (the binary; default build/bgkmap), BGKMAP_DATASETS (the datasets folder,
# datasets/locate.py: default ../shared/datasets beside the repository), IMG_DIR (default
# docs/img), THREADS (default 2).
# Takes about a quarter of an hour on 2 cores, most of it gpoctomap on the unstructured preset
# (docs/RESULTS.md says why).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/results}" && cd "${1:-$repo/out/results}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
img="${IMG_DIR:-$repo/docs/img}"
threads="${THREADS:-2}"
methods=(bgkl bgk counting octomap gpoctomap)

[ -x "$bgkmap" ] || { echo "results: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }
command -v python3 >/dev/null || { echo "results: python3 not found (scripts/setup.sh installs it)" >&2; exit 1; }
# The shared scans, or "" after one line naming what is missing.
sim_structured="$(python3 "$repo/datasets/locate.py" --require sim_structured --tag results)" || sim_structured=""
mkdir -p "$img"

log() { echo "results: $*" >&2; }

# The format each method's map is scored in: the BGK posteriors as .bgk, the trees as .ot of every
# cell's probability (--ot-values mean; .bt would keep only max-likelihood states).
map_file() {
  case "$1" in
    octomap | gpoctomap) echo "$2/$1.ot" ;;
    *) echo "$2/$1.bgk" ;;
  esac
}

# build_all DIR SCANS FLAGS...: every method on the same scans, one process each (peak memory per method).
build_all() {
  local dir="$1" scans="$2"
  shift 2
  for m in "${methods[@]}"; do
    local start=$SECONDS
    "$bgkmap" build "$scans" "$@" --threads "$threads" -q --method "$m" --ot-values mean -o "$(map_file "$m" "$dir")" \
      --report "$dir/$m.report.json"
    log "$(basename "$dir"): built $m in $((SECONDS - start)) s"
  done
}

# Build times depend on what else runs: the load is recorded beside the tables.
{
  echo "$(nproc) cores, $threads threads"
  echo "load average $(cut -d' ' -f1 /proc/loadavg) before the run"
} >"$out/machine.txt"
run_start=$SECONDS

for preset in structured unstructured; do
  dir="$out/$preset"
  "$bgkmap" simulate "$preset" -o "$dir" -q --overwrite
  build_all "$dir" "$dir/scans" --ds 0.1 --max-range 14 --backend cpu
  maps=()
  for m in "${methods[@]}"; do maps+=("$(map_file "$m" "$dir")"); done
  "$bgkmap" eval "${maps[@]}" --truth "$dir/scene.yaml" --json "$dir/eval.json" \
    --plot "$img/results_${preset}_roc.png" --title "$preset preset: the five methods against scene.yaml" \
    2>"$dir/eval.log"
  log "$preset: scored"
done

tables=()
if [ -n "$sim_structured" ]; then
  dir="$out/sim_structured"
  mkdir -p "$dir"
  la3dm=(--ds 0.1 --max-range 8 --resolution 0.1 --ell 0.2 --sigma0 0.1 --backend cpu)
  build_all "$dir" "$sim_structured" "${la3dm[@]}"
  "$bgkmap" eval --holdout 0.1 --seed 1 "$sim_structured" "${la3dm[@]}" --threads "$threads" \
    --methods "$(IFS=,; echo "${methods[*]}")" --json "$dir/eval.json" \
    --plot "$img/results_sim_structured_roc.png" --title "sim_structured, the five methods" 2>"$dir/eval.log"
  log "sim_structured: held-out beams scored"
else
  tables=(--without-sim-structured)
fi
{
  echo "load average $(cut -d' ' -f1 /proc/loadavg) after it ($(((SECONDS - run_start) / 60)) min)"
  echo "$(date -u +%Y-%m-%d)"
} >>"$out/machine.txt"

python3 "$repo/scripts/results_tables.py" "${tables[@]}" "$out" "${methods[@]}" >"$out/tables.md"
log "tables in $out/tables.md, figures in $img/results_*_roc.png"
