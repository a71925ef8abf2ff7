#!/usr/bin/env python3
"""Runs `bgkmap build ... --report` N times and prints the median of the report's figures.

Usage: bench/report_median.py N BGKMAP_BINARY BUILD_ARGS...
The runs' JSON reports go to a temporary folder; the output is one JSON object with the medians
of insert_s, its stages and pairs per second, and the back end, device and threads.
"""
import json
import statistics
import subprocess
import sys
import tempfile
import os


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    runs, binary, args = int(sys.argv[1]), sys.argv[2], sys.argv[3:]
    reports = []
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(runs):
            path = os.path.join(tmp, f"r{i}.json")
            subprocess.run([binary, "build", "-q", *args, "--report", path], check=True)
            with open(path) as f:
                reports.append(json.load(f))
    med = lambda key: statistics.median(r["timing"][key] for r in reports)
    last = reports[-1]
    pairs = last["counts"]["pairs_evaluated"]
    out = {
        "runs": runs,
        "args": args,
        "backend": last["backend"],
        "insert_s": med("insert_s"),
        "insert_s_min": min(r["timing"]["insert_s"] for r in reports),
        "insert_s_max": max(r["timing"]["insert_s"] for r in reports),
        **{k: med(k) for k in ("preprocess_s", "bucket_s", "compute_s", "update_s", "read_s")},
        "pairs_evaluated": pairs,
        "pairs_within_l": last["counts"]["pairs_within_l"],
        "pairs_per_s_of_compute": pairs / med("compute_s"),
        "blocks_touched": last["counts"]["blocks_touched"],
        "peak_rss_mb": statistics.median(r["peak_rss_mb"] for r in reports),
    }
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
