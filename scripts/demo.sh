#!/usr/bin/env bash
# The README's first command ends here: simulate the built-in `structured` scene and map it.
# Usage: scripts/demo.sh [BUILD_DIR] [OUT_DIR]
set -euo pipefail
build_dir="${1:-build}"
out_dir="${2:-demo}"
bgkmap="$build_dir/bgkmap"
[ -x "$bgkmap" ] || { echo "demo: $bgkmap not found; build first (cmake --build $build_dir)" >&2; exit 1; }
"$bgkmap" simulate structured -o "$out_dir"
"$bgkmap" build "$out_dir/scans" -o "$out_dir/map.bgk" -o "$out_dir/map.ot" -o "$out_dir/map.bt" \
  --report "$out_dir/report.json" --ds 0.1 --max-range 14
"$bgkmap" info "$out_dir/map.bgk"
"$bgkmap" view "$out_dir/map.bgk" -o "$out_dir/map.html"
echo "demo: maps in $out_dir/ (map.html opens in a web browser, map.ot / map.bt in octovis), report in $out_dir/report.json"
