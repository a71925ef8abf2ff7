#!/usr/bin/env bash
# Reproduces docs/RESULTS.md's "Pose uncertainty" section: the structured scene simulated with
# odometry drift (bgkmap simulate --drift, one trajectory per seed), each method built from the
# drifted scans ignoring the pose uncertainty and with the true covariance (--pose-covariance),
# by the expected sub-map (--pose-fusion submap, the default) and by the expected kernel
# (--pose-fusion kernel), and the maps of one scene
# scored together against the true scene (eval --truth: one evaluated box for all of them, so
# their all-cells figures cover the same cells).
# Writes OUT_DIR/s<seed>/<drift>/ (scans, maps, eval JSON), OUT_DIR/pose_runs.md (every run),
# OUT_DIR/pose_table.md (means over the seeds) and, for the first seed and the drift named by
# PICTURE, docs/img/pose_drift_<method>_{plain,ek,submap}.png.
#
# Usage: scripts/pose_drift.sh [OUT_DIR]        (default OUT_DIR: out/pose in the repository)
# Environment: BGKMAP (default build/bgkmap), THREADS (default 2), SCANS (default 20),
# DRIFTS (default "0.01,0.002 0.02,0.005 0.04,0.01": per-scan XY,YAW increments), SEEDS (default
# "1 2 3 4": simulate --seed, drawing the range noise and the drift), METHODS (default "bgkl"),
# PICTURE (default 0.02,0.005), IMG_DIR (default docs/img), SENSOR (simulate --sensor; default the
# preset's), PLANE_Z (given: planar maps, build --2d --plane-z PLANE_Z, rendered at that height;
# e.g. SENSOR=planar PLANE_Z=1 for gpom and wgpom, which are slow in 3-D), EK_CORRELATIONS (gpom
# and wgpom: more expected-kernel maps, one per --gp-input-correlation named, e.g. "independent
# scan"; the plain "expected kernel" rows take the default, trajectory).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/pose}" && cd "${1:-$repo/out/pose}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
threads="${THREADS:-2}"
scans="${SCANS:-20}"
drifts="${DRIFTS:-0.01,0.002 0.02,0.005 0.04,0.01}"
seeds="${SEEDS:-1 2 3 4}"
methods="${METHODS:-bgkl}"
picture="${PICTURE:-0.02,0.005}"
img="${IMG_DIR:-$repo/docs/img}"
sensor=()
[ -n "${SENSOR:-}" ] && sensor=(--sensor "$SENSOR")
planar=()
render_z=1.0
[ -n "${PLANE_Z:-}" ] && planar=(--2d --plane-z "$PLANE_Z") && render_z="$PLANE_Z"
[ -x "$bgkmap" ] || { echo "pose_drift: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }
mkdir -p "$img"
export OMP_WAIT_POLICY=passive

runs="$out/pose_runs.md"
{
  echo "| seed | drift XY,YAW per scan | method | pose | NLL all cells | AUC all cells | NLL observed | AUC observed | insert s |"
  echo "|---|---|---|---|---|---|---|---|---|"
} > "$runs"
first_seed="${seeds%% *}"
for seed in $seeds; do
  for drift in $drifts; do
    dir="$out/s$seed/${drift//,/_}"
    "$bgkmap" simulate structured -o "$dir" --scans "$scans" --drift "$drift" --seed "$seed" "${sensor[@]}" --overwrite -q
    for method in $methods; do
      maps=()
      poses="plain ek submap"
      case "$method" in gpom | wgpom) for c in ${EK_CORRELATIONS:-}; do poses+=" ek-$c"; done ;; esac
      ext=bgk
      case "$method" in gpom | wgpom) ext=bt ;; esac
      for pose in $poses; do
        extra=()
        [ "$pose" = ek ] && extra=(--pose-covariance "$dir/poses.txt" --pose-fusion kernel)
        [ "$pose" = submap ] && extra=(--pose-covariance "$dir/poses.txt" --pose-fusion submap)
        case "$pose" in ek-*) extra=(--pose-covariance "$dir/poses.txt" --pose-fusion kernel --gp-input-correlation "${pose#ek-}") ;; esac
        map="$dir/${method}_$pose.$ext"
        "$bgkmap" build "$dir/scans" --max-range 14 --method "$method" --backend cpu --threads "$threads" \
          "${planar[@]}" "${extra[@]}" -o "$map" --report "$dir/${method}_$pose.report.json" -q
        maps+=("$map")
        if [ "$seed" = "$first_seed" ] && [ "$drift" = "$picture" ] && [ "${pose#ek-}" = "$pose" ]; then
          "$bgkmap" render "$map" --z "$render_z" -o "$img/pose_drift_${method}_$pose.png" > /dev/null
        fi
      done
      "$bgkmap" eval "${maps[@]}" --truth "$dir/truth.bt" --json "$dir/$method.eval.json" > /dev/null
      python3 - "$dir/$method.eval.json" "$dir" "$seed" "$drift" "$method" $poses >> "$runs" <<'PY'
import json, sys
maps = json.load(open(sys.argv[1]))["maps"]
names = {"plain": "ignored", "ek": "true covariance, expected kernel", "submap": "true covariance, expected sub-map",
         "ek-independent": "true covariance, expected kernel, independent inputs",
         "ek-scan": "true covariance, expected kernel, inputs correlated per scan",
         "ek-trajectory": "true covariance, expected kernel, inputs correlated over the trajectory"}
for m, pose in zip(maps, sys.argv[6:]):
    a, o = m["protocols"]["all_cells"], m["protocols"]["observed_cells"]
    r = json.load(open(f"{sys.argv[2]}/{sys.argv[5]}_{pose}.report.json"))
    print(f"| {sys.argv[3]} | {sys.argv[4]} | {sys.argv[5]} | {names[pose]} | {a['nll']:.4f} | {a['auc']:.4f} | "
          f"{o['nll']:.4f} | {o['auc']:.4f} | {r['timing']['insert_s']:.1f} |")
PY
    done
  done
done
python3 - "$runs" > "$out/pose_table.md" <<'PY'
import sys
from collections import defaultdict
rows = defaultdict(list)
order = []
for line in open(sys.argv[1]).read().splitlines()[2:]:
    c = [x.strip() for x in line.strip("|").split("|")]
    key = (c[1], c[2], c[3])
    if key not in rows: order.append(key)
    rows[key].append((c[0], float(c[4]), float(c[5]), float(c[8])))
print("| drift XY,YAW per scan | method | pose | NLL all cells, mean | per seed | AUC all cells, mean | insert s, mean |")
print("|---|---|---|---|---|---|---|")
for key in order:
    r = rows[key]
    mean = lambda i: sum(x[i] for x in r) / len(r)
    per = " ".join(f"{x[1]:.4f}" for x in r)
    print(f"| {key[0]} | {key[1]} | {key[2]} | {mean(1):.4f} | {per} | {mean(2):.4f} | {mean(3):.1f} |")
PY
cat "$out/pose_runs.md" "$out/pose_table.md"
