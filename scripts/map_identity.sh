#!/usr/bin/env bash
# Byte identity of the maps every method builds, for refactors that must not change a map: builds a
# fixed set of maps (each method on sim_structured, campus scans and the first Intel scans; the CPU
# path and OpenCL where the method has a device path) and prints one "case sha256" line each.
#   record FILE   write the lines to FILE
#   check FILE    build again and compare with FILE; exits 1 naming every case that differs
# Environment: BGKMAP (default build/bgkmap), BGKMAP_DATASETS (default ../shared/datasets),
# CASES (an extended regex: only the cases whose name matches), BACKENDS (default "cpu opencl"),
# MAP_IDENTITY_INPUTS (where the campus scans and Intel excerpts are made once; default
# /tmp/bgkmap-map-identity-inputs).
# Takes about 5 minutes on 2 busy cores.
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
datasets="${BGKMAP_DATASETS:-$repo/../shared/datasets}"
backends="${BACKENDS:-cpu opencl}"
mode="${1:-}"
file="${2:-}"
if [[ "$mode" != record && "$mode" != check ]] || [[ -z "$file" ]]; then
  echo "usage: scripts/map_identity.sh record|check FILE" >&2
  exit 2
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# A .bgk records its inputs' paths (for --resume), so the derived inputs live at one fixed place.
inputs="${MAP_IDENTITY_INPUTS:-/tmp/bgkmap-map-identity-inputs}"
mkdir -p "$inputs"

# Inputs: the 12 sim_structured scans, their first 2, 30 campus scans (octomap: 10), the first 100
# Intel scans (gpoctomap: 20).
sim=("$datasets"/sim_structured/scan_*.pcd)
sim2=("${sim[@]:0:2}")
[[ -d "$inputs/campus/scans" ]] || "$bgkmap" simulate campus -q --scans 30 --truth-resolution 0 -o "$inputs/campus"
campus=("$inputs"/campus/scans/*.pcd)
for n in 100 20; do
  [[ -s "$inputs/intel$n.log" ]] ||
    zcat "$datasets/carmen/intel-corrected.log.gz" | awk -v n="$n" '/^FLASER/ && k++ < n' > "$inputs/intel$n.log"
done
intel=("$inputs/intel100.log")
intel20=("$inputs/intel20.log")
campus10=("${campus[@]:0:10}")

sim_flags=(--resolution 0.1 --ell 0.2 --sigma0 0.1 --ds 0.1 --max-range 8)
campus_flags=(--resolution 0.2 --ell 0.6 --ds 0.5 --max-range 50)
intel_flags=(--resolution 0.1 --ell 0.3 --max-range 30)

# name method inputs-variable flags-variable: one case per back end the method has a device path on.
run_case() {
  local name="$1" method="$2" inputs="$3" flags="$4" device="$5"
  local -n in_ref="$inputs" flags_ref="$flags"
  local ext=ot extra=(--ot-values mean)
  case "$method" in bgkl | bgk | counting) ext=bgk extra=() ;; esac
  local list=cpu
  [[ "$device" == device ]] && list="$backends"
  for backend in $list; do
    local case_name="$name-$method-$backend"
    [[ -n "${CASES:-}" && ! "$case_name" =~ $CASES ]] && continue
    local out="$work/$case_name.$ext" start=$SECONDS
    "$bgkmap" build "${in_ref[@]}" -q --method "$method" "${flags_ref[@]}" "${extra[@]}" --backend "$backend" \
      --threads 2 -o "$out"
    echo "$case_name $(sha256sum < "$out" | cut -c1-64)"
    echo "map_identity: $case_name built in $((SECONDS - start)) s" >&2
  done
}

{
  for m in bgkl bgk; do run_case sim "$m" sim sim_flags device; done
  for m in counting octomap; do run_case sim "$m" sim sim_flags cpu; done
  run_case sim2 gpoctomap sim2 sim_flags cpu
  for m in gpom wgpom bhm; do run_case sim2 "$m" sim2 sim_flags device; done
  run_case campus bgkl campus campus_flags device
  run_case campus counting campus campus_flags cpu
  run_case campus10 octomap campus10 campus_flags cpu
  for m in bgkl bgk; do run_case intel "$m" intel intel_flags device; done
  for m in counting octomap; do run_case intel "$m" intel intel_flags cpu; done
  run_case intel20 gpoctomap intel20 intel_flags cpu
  for m in gpom wgpom bhm; do run_case intel "$m" intel intel_flags device; done
} > "$work/hashes.txt"

if [[ "$mode" == record ]]; then
  cp "$work/hashes.txt" "$file"
  cat "$file"
  exit 0
fi
status=0
while read -r name hash; do
  want="$(awk -v n="$name" '$1 == n {print $2}' "$file")"
  if [[ -z "$want" ]]; then
    echo "map_identity: $name not in $file" >&2
    status=1
  elif [[ "$want" != "$hash" ]]; then
    echo "map_identity: $name differs" >&2
    status=1
  else
    echo "map_identity: $name identical"
  fi
done < "$work/hashes.txt"
exit "$status"
