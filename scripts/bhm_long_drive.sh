#!/usr/bin/env bash
# bhm on a long simulated drive (docs/BENCHMARKS.md, "bhm on a long drive"): the campus preset
# (~600 x 350 m) seen by the planar scanner (1080 beams over 270 degrees, 30 m) from the car, 300
# scans around its 2 km loop, mapped with --method bhm (free space as sampled points; FREE="points
# beams" adds the exact beams, many times slower on these 30 m beams). Writes the build reports, docs/img/bhm_long_drive_per_scan.png (insert time per
# scan against the scan's number, medians of 15 scans) and prints a markdown table.
#
# Usage: scripts/bhm_long_drive.sh [OUT_DIR]   (default OUT_DIR: out/bhm_long_drive in the repository)
# Environment: BGKMAP (default build/bgkmap), PLOT (default build/bench/plot_per_scan), IMG_DIR
# (default docs/img), THREADS (default 2), SCANS (default 300), MEMORY_CAP (bytes, default 4e9).
set -euo pipefail

repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$(mkdir -p "${1:-$repo/out/bhm_long_drive}" && cd "${1:-$repo/out/bhm_long_drive}" && pwd)"
bgkmap="${BGKMAP:-$repo/build/bgkmap}"
plot="${PLOT:-$repo/build/bench/plot_per_scan}"
img="${IMG_DIR:-$repo/docs/img}"
threads="${THREADS:-2}"
cap="${MEMORY_CAP:-4000000000}"
[ -x "$bgkmap" ] || { echo "bhm_long_drive: $bgkmap not found; build bgkmap first (or set BGKMAP)" >&2; exit 1; }

"$bgkmap" simulate campus --sensor planar --scans "${SCANS:-300}" --truth-resolution 0 -o "$out/campus" --overwrite -q
echo "| --bhm-free | scans | insert s | median ms per scan, scans 1-50 / 126-175 / 251-300 | blocks | peak RSS MB |"
echo "|---|---|---|---|---|---|"
plots=()
for free in ${FREE:-points}; do
  (ulimit -v $((cap / 1024)); "$bgkmap" build "$out/campus/scans" --method bhm --bhm-free "$free" --max-range 30 \
    --resolution 0.2 --ds 0.1 --backend cpu --threads "$threads" -o "$out/$free.ot" --report "$out/$free.json" -q)
  python3 - "$out/$free.json" "$free" <<'EOF'
import json, statistics, sys
r = json.load(open(sys.argv[1]))
t = r["timing"]["per_scan"]
med = lambda a: 1000 * statistics.median(a)
n = len(t)
parts = " / ".join(f"{med(t[a:a + 50]):.0f}" for a in (0, n // 2 - 25, n - 50))
print(f"| {sys.argv[2]} | {r['counts']['scans']} | {r['timing']['insert_s']:.1f} | {parts} | "
      f"{r['counts']['blocks_touched']} | {r['peak_rss_mb']:.0f} |")
EOF
  plots+=("$free=$out/$free.json")
done
"$plot" "$img/bhm_long_drive_per_scan.png" "bhm, ${SCANS:-300} scans, campus" 15 "${plots[@]}"
