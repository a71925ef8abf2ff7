#!/usr/bin/env bash
# What bhm's block approximation costs (docs/RESULTS.md, "bhm: blocks against the full
# covariance"): the small planar scene bench/scenes/bhm_room.yaml, whose hinges all lie in one
# block of 48 x 48 supports, mapped with --bhm-block-side 4, 8 (the 2-D default), 16, 24 and 48
# (one block: the exact full-covariance model) and scored on the same held-out scans
# (eval --holdout 0.25 --split scans --run-length 2 --seed 1). Prints a markdown table.
#
# Usage: scripts/bhm_blocks.sh [OUT_DIR]       (default OUT_DIR: out/bhm_blocks in the repository)
# Environment: BGKMAP (default build/bgkmap), THREADS (default 2), SIDES (default "4 8 16 24 48"),
# MEMORY_CAP (bytes of address space per run, default 4e9).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/bhm_blocks}" && cd "${1:-$repo/out/bhm_blocks}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
threads="${THREADS:-2}"
cap="${MEMORY_CAP:-4000000000}"
[ -x "$bgkmap" ] || { echo "bhm_blocks: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }

"$bgkmap" simulate "$repo/bench/scenes/bhm_room.yaml" -o "$out/room" --truth-resolution 0 --overwrite -q
echo "| --bhm-block-side | supports per block | AUC | AP | NLL | accuracy | eval wall s |"
echo "|---|---|---|---|---|---|---|"
for side in ${SIDES:-4 8 16 24 48}; do
  start=$(date +%s.%N)
  (ulimit -v $((cap / 1024)); "$bgkmap" eval --holdout 0.25 --split scans --run-length 2 --seed 1 "$out/room/scans" \
    --resolution 0.1 --backend cpu --threads "$threads" --method bhm \
    --bhm-block-side "$side" --json "$out/side$side.json" >/dev/null)
  end=$(date +%s.%N)
  python3 - "$out/side$side.json" "$side" "$(echo "$end - $start" | bc)" <<'EOF'
import json, sys
m = json.load(open(sys.argv[1]))
side = int(sys.argv[2])
print(f"| {side} | {side * side} | {m['auc']:.4f} | {m['average_precision']:.4f} | {m['nll']:.4f} | {m['accuracy']:.4f} | {float(sys.argv[3]):.1f} |")
EOF
done
