#!/usr/bin/env bash
# Reproduces docs/RESULTS.md's "Pose uncertainty" section: the structured scene simulated with
# odometry drift (bgkmap simulate --drift), each method built from the drifted scans without and
# with their true pose covariance (--pose-covariance: the expected kernel), scored against the
# true scene (eval --truth). Writes OUT_DIR/<drift>/ (scans, maps, eval JSON), OUT_DIR/pose_table.md
# and, for the drift named by PICTURE, docs/img/pose_drift_<method>_{plain,ek}.png.
#
# Usage: scripts/pose_drift.sh [OUT_DIR]        (default OUT_DIR: out/pose in the repository)
# Environment: BGKMAP (default build/bgkmap), THREADS (default 2), SCANS (default 20),
# DRIFTS (default "0.01,0.002 0.02,0.005 0.04,0.01": per-scan XY,YAW increments), METHODS
# (default "bgkl bgk"), PICTURE (default 0.02,0.005), IMG_DIR (default docs/img).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/pose}" && cd "${1:-$repo/out/pose}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
threads="${THREADS:-2}"
scans="${SCANS:-20}"
drifts="${DRIFTS:-0.01,0.002 0.02,0.005 0.04,0.01}"
methods="${METHODS:-bgkl bgk}"
picture="${PICTURE:-0.02,0.005}"
img="${IMG_DIR:-$repo/docs/img}"
[ -x "$bgkmap" ] || { echo "pose_drift: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }
mkdir -p "$img"
export OMP_WAIT_POLICY=passive

table="$out/pose_table.md"
{
  echo "| drift XY,YAW per scan | method | pose | NLL all cells | AUC all cells | NLL observed | AUC observed | insert s |"
  echo "|---|---|---|---|---|---|---|---|"
} > "$table"
for drift in $drifts; do
  dir="$out/${drift//,/_}"
  "$bgkmap" simulate structured -o "$dir" --scans "$scans" --drift "$drift" --overwrite -q
  for method in $methods; do
    for pose in plain ek; do
      extra=()
      [ "$pose" = ek ] && extra=(--pose-covariance "$dir/poses.txt")
      map="$dir/${method}_$pose.bgk"
      "$bgkmap" build "$dir/scans" --max-range 14 --method "$method" --backend cpu --threads "$threads" \
        "${extra[@]}" -o "$map" --report "$dir/${method}_$pose.report.json" -q
      "$bgkmap" eval "$map" --truth "$dir/truth.bt" --json "$dir/${method}_$pose.eval.json" > /dev/null
      if [ "$drift" = "$picture" ]; then
        "$bgkmap" render "$map" --z 1.0 -o "$img/pose_drift_${method}_$pose.png" > /dev/null
      fi
      python3 - "$dir/${method}_$pose.eval.json" "$dir/${method}_$pose.report.json" "$drift" "$method" "$pose" >> "$table" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))["maps"][0]["protocols"]
r = json.load(open(sys.argv[2]))
a, o = e["all_cells"], e["observed_cells"]
pose = "true covariance (EK)" if sys.argv[5] == "ek" else "ignored"
print(f"| {sys.argv[3]} | {sys.argv[4]} | {pose} | {a['nll']:.4f} | {a['auc']:.4f} | {o['nll']:.4f} | {o['auc']:.4f} | {r['timing']['insert_s']:.1f} |")
PY
    done
  done
done
cat "$table"
