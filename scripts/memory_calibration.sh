#!/usr/bin/env bash
# How well --max-memory's estimates hold, method by method: each method builds the same scans once
# under the default limit (its peak resident memory, the report's peak_rss_mb), then again with
# --max-memory at 90 %, 75 % and 50 % of that peak. A build under a limit below its own peak must
# either be refused before the step that would not fit (exit 1, the one-line error) or finish
# within the limit; one that finishes with its peak above the limit is a miss of the estimates.
# Then the smallest limit (1, 1.25, 1.5, 2, 3, 4, 6 or 8 times the peak) it runs under: how far
# the estimates are on the safe side.
#
#   scripts/memory_calibration.sh BGKMAP OUT [SCAN...]   (default: 3 scans of the structured preset)
set -euo pipefail
bgkmap="$1" out="$2"
shift 2
mkdir -p "$out"
scans=("$@")
if [ ${#scans[@]} -eq 0 ]; then
  [ -d "$out/sim" ] || "$bgkmap" simulate structured -o "$out/sim" -q
  scans=("$out"/sim/scans/scan_0000[0-2].pcd)
fi
common=(--max-range 14 --backend cpu --threads 2 -q)
declare -A extra=([gpoctomap]="--ds 0.1")
printf '| method | peak MB (default limit) | limit 90 %% | limit 75 %% | limit 50 %% | smallest limit it runs under |\n|---|---:|---|---|---|---|\n'
for m in bgkl bgk counting octomap gpoctomap gpom wgpom bhm; do
  # shellcheck disable=SC2086
  "$bgkmap" build "${scans[@]}" --method "$m" ${extra[$m]:-} "${common[@]}" -o "$out/$m.ot" --report "$out/$m.json"
  peak=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['peak_rss_mb'])" "$out/$m.json")
  row="| $m | $(printf '%.0f' "$peak") |"
  for f in 0.9 0.75 0.5; do
    limit=$(python3 -c "print(int($peak * $f))")
    rc=0
    # shellcheck disable=SC2086
    "$bgkmap" build "${scans[@]}" --method "$m" ${extra[$m]:-} "${common[@]}" --max-memory "${limit}M" \
      -o "$out/$m.$f.ot" --report "$out/$m.$f.json" 2>"$out/$m.$f.err" || rc=$?
    if [ "$rc" -ne 0 ]; then
      row+=" refused ($(grep -c . "$out/$m.$f.err") line) |"
    else
      got=$(python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['peak_rss_mb'])" "$out/$m.$f.json")
      verdict=$(python3 -c "print('within' if $got <= $limit else 'MISS: over')")
      row+=" finished, peak $(printf '%.0f' "$got") MB ($verdict ${limit} MB) |"
    fi
  done
  smallest="over 8 x peak"
  for f in 1 1.25 1.5 2 3 4 6 8; do
    limit=$(python3 -c "print(int($peak * $f) + 1)")
    # shellcheck disable=SC2086
    if "$bgkmap" build "${scans[@]}" --method "$m" ${extra[$m]:-} "${common[@]}" --max-memory "${limit}M" \
         -o "$out/$m.s.ot" 2>/dev/null; then
      smallest="$f x peak (${limit} MB)"
      break
    fi
  done
  echo "$row $smallest |"
done
