#!/usr/bin/env bash
# The dynamic-scene table: on the `dynamic` preset (a door that opens at scan 20, a car that leaves
# at scan 15, two walkers; 40 scans), each method built scan by scan and scored after every scan
# (`bgkmap eval --per-scan`) against the scene at that time. Columns, from the last scan's row:
# static AUC (all cells, and the cells with evidence), the removed-object cells seen through 3 or
# more scans before reading free, and the trail cells the walkers left reading occupied. Also
# draws bgkl's final map with and without forgetting, and its changes from scan 14 to the end.
#   scripts/dynamic_results.sh [HALF_LIFE ...]   forgetting half-lives (scans) for bgkl; default
#                                                5 10 20 when `build --help` lists --forget-half-life,
#                                                none otherwise
# Environment: BGKMAP (default build/bgkmap), OUT (default /tmp/bgkmap-dynamic-results), EVERY
# (score every this many scans, default 1). Takes about 5 minutes on 2 busy cores (bhm 4 of them).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
out="${OUT:-/tmp/bgkmap-dynamic-results}"
every="${EVERY:-1}"
half_lives=("$@")
has_forget=0
"$bgkmap" build --help | grep -q -- '--forget-half-life' && has_forget=1
if ((${#half_lives[@]} == 0 && has_forget)); then half_lives=(5 10 20); fi
if ((${#half_lives[@]} > 0 && !has_forget)); then
  echo "dynamic_results.sh: this bgkmap has no --forget-half-life; run without half-lives" >&2
  exit 2
fi

mkdir -p "$out"
"$bgkmap" simulate dynamic -q --overwrite -o "$out/sim"
scans="$out/sim/scans"
scene="$out/sim/scene.yaml"
flags=(--max-range 13)

# name|build flags
cases=("bgkl|--method bgkl")
for h in "${half_lives[@]}"; do cases+=("bgkl forget $h|--method bgkl --forget-half-life $h"); done
cases+=("octomap|--method octomap" "bhm|--method bhm")

echo "| method | static AUC (all cells) | static AUC (observed) | removed cells free 3 scans after seen through | trail cells occupied | seconds |"
echo "|---|---|---|---|---|---|"
for c in "${cases[@]}"; do
  name="${c%%|*}"
  read -r -a method_flags <<< "${c#*|}"
  json="$out/$(echo "$name" | tr ' ' '_').json"
  start=$(date +%s.%N)
  "$bgkmap" eval -q "$scans" --truth "$scene" --per-scan "$every" "${flags[@]}" "${method_flags[@]}" --json "$json"
  seconds=$(echo "$(date +%s.%N) - $start" | bc)
  python3 - "$json" "$name" "$seconds" <<'PY'
import json, sys
row = json.load(open(sys.argv[1]))["rows"][-1]
def f(v, d=4):
    return "n/a" if v is None else f"{v:.{d}f}"
s = row["static_cells"]
r, t = row["removed_cells"], row["trail_cells"]
print(f"| {sys.argv[2]} | {f(s['all_cells']['auc'])} | {f(s['observed_cells']['auc'])} | "
      f"{f(r['settled_read_free'], 3)} of {r['settled_cells']} | {f(t['read_occupied'], 3)} of {t['cells']} | "
      f"{float(sys.argv[3]):.1f} |")
PY
done

# Pictures: bgkl's final map without (and with the middle half-life of) forgetting, and what
# changed between scan 14 (the car still parked, the door shut) and the end.
first=("$scans"/scan_000{00..14}.pcd)
"$bgkmap" build -q "${first[@]}" "${flags[@]}" -o "$out/bgkl_scan14.bgk"
"$bgkmap" build -q "$scans" "${flags[@]}" -o "$out/bgkl.bgk"
"$bgkmap" render "$out/bgkl.bgk" --z 0.55 -o "$out/bgkl.png" --title "bgkl, no forgetting, after 40 scans"
"$bgkmap" diff -q "$out/bgkl_scan14.bgk" "$out/bgkl.bgk" -o "$out/bgkl_changes.png" --z 0.55 --json "$out/bgkl_changes.json"
if ((${#half_lives[@]} > 0)); then
  h="${half_lives[$(( ${#half_lives[@]} / 2 ))]}"
  "$bgkmap" build -q "$scans" "${flags[@]}" --forget-half-life "$h" -o "$out/bgkl_forget$h.bgk"
  "$bgkmap" render "$out/bgkl_forget$h.bgk" --z 0.55 -o "$out/bgkl_forget$h.png" \
    --title "bgkl, forgetting half-life $h scans, after 40 scans"
fi
echo "pictures and JSON rows in $out" >&2
