#!/usr/bin/env python3
"""Prints the CPU vs OpenCL vs OctoMap throughput table of `bgkmap build` (issue #6).

Usage: bench/throughput_table.py [--bgkmap build/bgkmap] [--runs 5] [--threads 2]
                                 [--datasets DIR] [--campus DIR] [--campus-scans 30]
                                 [--campus-runs 3] [--skip-campus] [--skip-sim-structured] [--intel]
                                 [--json OUT.json]

For each dataset it builds with `--method bgkl --backend cpu`, `--method bgkl --backend opencl`
and `--method octomap`, round-robin (one run of each, then the next round), so that a slow
spell of a shared machine hits every configuration alike, and prints the median of the JSON
report's insert_s (seconds spent inserting the scans: preprocessing, bucketing, evaluation; not
reading files or writing the map) with the ratios the issue asks for, per round and as medians,
beside the median bucket_s and, for OpenCL, the kernels' device time (device_kernel_s).

Datasets and settings (--datasets: default datasets/locate.py's folder, $BGKMAP_DATASETS or
../shared/datasets beside the checkout; a dataset missing from it is named on one line and skipped):
  sim_structured  DATASETS/sim_structured, la3dm settings
                  (--resolution 0.1 --ell 0.2 --sigma0 0.1 --ds 0.1 --max-range 8)
  campus          the simulator's campus preset (`bgkmap simulate campus -o DIR`; simulated into
                  --campus DIR when DIR has no scans yet: ~1 GB, 1-2 minutes), its first
                  --campus-scans scans (0 = all 3000; each scan costs about a second of
                  BGK-L on 2 cores, see docs/BENCHMARKS.md), la3dm's large-map settings
                  (--resolution 0.2 --ell 0.6 --ds 0.5 --max-range 50)
  intel           (--intel) the whole Intel Research Lab log, DATASETS/carmen/intel-corrected.log.gz
                  (910 planar scans of 180 beams), --resolution 0.1 --max-range 20
pairs/s is pairs_evaluated / compute_s (the kernels' stage), median over the runs.
"""
import argparse
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "datasets"))
import locate  # noqa: E402  (datasets/locate.py)

SIM_STRUCTURED_FLAGS = ["--resolution", "0.1", "--ell", "0.2", "--sigma0", "0.1", "--ds", "0.1", "--max-range", "8"]
CAMPUS_FLAGS = ["--resolution", "0.2", "--ell", "0.6", "--ds", "0.5", "--max-range", "50"]
INTEL_FLAGS = ["--resolution", "0.1", "--max-range", "20"]
CONFIGS = [  # (label, flags, output extension)
    ("bgkl cpu", ["--method", "bgkl", "--backend", "cpu"], ".bgk"),
    ("bgkl opencl", ["--method", "bgkl", "--backend", "opencl"], ".bgk"),
    ("octomap", ["--method", "octomap"], ".ot"),
]


def natural_key(name):
    return [int(t) if t.isdigit() else t for t in re.split(r"(\d+)", name)]


def campus_inputs(folder, scans, binary):
    scan_dir = os.path.join(folder, "scans")
    if not os.path.isdir(scan_dir):
        print(f"throughput: simulating the campus preset into {folder}", file=sys.stderr)
        subprocess.run([binary, "simulate", "campus", "-o", folder], check=True)
    files = sorted((f for f in os.listdir(scan_dir) if f.endswith(".pcd")), key=natural_key)
    if scans > 0:
        files = files[:scans]
    return [os.path.join(scan_dir, f) for f in files]


def build(binary, inputs, flags, threads, ext, tmp, tag):
    report = os.path.join(tmp, tag + ".json")
    out = os.path.join(tmp, tag + ext)
    subprocess.run([binary, "build", "-q", *inputs, *flags, "--threads", str(threads), "-o", out, "--report", report],
                   check=True)
    with open(report) as f:
        return json.load(f)


def measure(binary, name, inputs, flags, runs, threads):
    rows = {label: [] for label, _, _ in CONFIGS}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(runs):
            for label, config_flags, ext in CONFIGS:
                rep = build(binary, inputs, flags + config_flags, threads, ext, tmp, f"{label.replace(' ', '_')}_{r}")
                rows[label].append(rep)
                print(f"throughput: {name} run {r + 1}/{runs} {label}: insert_s {rep['timing']['insert_s']:.3f}",
                      file=sys.stderr)
    return rows


def summarize(name, rows):
    ins = {label: [rep["timing"]["insert_s"] for rep in reps] for label, reps in rows.items()}
    med = {label: statistics.median(v) for label, v in ins.items()}
    per_round = lambda a, b: statistics.median(x / y for x, y in zip(ins[a], ins[b]))
    out = {"dataset": name, "runs": len(ins["octomap"]), "configs": {}}
    for label, reps in rows.items():
        last = reps[-1]
        counts = last["counts"]
        out["configs"][label] = {
            "insert_s_median": med[label],
            "insert_s_min": min(ins[label]),
            "insert_s_max": max(ins[label]),
            "device": last["backend"].get("device"),
            "threads": last["backend"].get("threads"),
            "note": last["backend"].get("note", ""),
            "pairs_evaluated": counts.get("pairs_evaluated"),
            "share_within_l": counts.get("share_within_l"),
            "peak_rss_mb": statistics.median(r["peak_rss_mb"] for r in reps),
            "bucket_s_median": statistics.median(r["timing"].get("bucket_s", 0.0) for r in reps),
            "device_kernel_s_median": statistics.median(r["timing"].get("device_kernel_s", 0.0) for r in reps),
            "pairs_per_s_median": statistics.median(r["timing"].get("pairs_per_s", 0.0) for r in reps),
            "scans": counts.get("scans"),
        }
    out["cpu_over_octomap"] = per_round("bgkl cpu", "octomap")
    out["opencl_over_cpu"] = per_round("bgkl opencl", "bgkl cpu")
    return out


def print_table(summaries):
    print("| dataset | configuration | insert_s median (min-max) | bucket_s | device kernels | pairs evaluated "
          "| pairs/s | within l | peak RSS | device |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for s in summaries:
        for label, c in s["configs"].items():
            pairs = f"{c['pairs_evaluated'] / 1e6:.1f} M" if c["pairs_evaluated"] else "-"
            rate = f"{c['pairs_per_s_median'] / 1e6:.0f} M" if c["pairs_per_s_median"] and label != "octomap" else "-"
            share = f"{100 * c['share_within_l']:.0f}%" if c["share_within_l"] else "-"
            device = c["device"] + (f" ({c['threads']} threads)" if label == "bgkl cpu" else "")
            bucket = f"{c['bucket_s_median']:.3f} s" if label != "octomap" else "-"
            # OpenCL only: the kernels' own device time, which overlaps the host's bucketing.
            kernels = f"{c['device_kernel_s_median']:.3f} s" if label == "bgkl opencl" else "-"
            print(f"| {s['dataset']} ({c['scans']} scans) | {label} | {c['insert_s_median']:.3f} s "
                  f"({c['insert_s_min']:.3f}-{c['insert_s_max']:.3f}) | {bucket} | {kernels} | {pairs} | {rate} | {share} | "
                  f"{c['peak_rss_mb']:.0f} MB | {device} |")
    print()
    for s in summaries:
        print(f"{s['dataset']}: bgkl cpu / octomap = {s['cpu_over_octomap']:.2f}x, "
              f"bgkl opencl / bgkl cpu = {s['opencl_over_cpu']:.2f}x (medians of per-round ratios, {s['runs']} runs)")


def present_summary(args, name, relative, flags, runs):
    """[the summary of one dataset of the datasets folder], or [] with one line when it is missing."""
    try:
        path = locate.require(relative, "throughput", args.datasets)
    except locate.Missing as missing:
        print(missing, file=sys.stderr)
        return []
    return [summarize(name, measure(args.bgkmap, name, [str(path)], flags, runs, args.threads))]


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bgkmap", default=os.path.join(here, "..", "build", "bgkmap"))
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--datasets", default=str(locate.datasets_dir()))
    parser.add_argument("--campus", default=os.path.join(tempfile.gettempdir(), "bgkmap-campus"))
    parser.add_argument("--campus-scans", type=int, default=30)
    parser.add_argument("--campus-runs", type=int, default=3)
    parser.add_argument("--skip-campus", action="store_true")
    parser.add_argument("--skip-sim-structured", action="store_true")
    parser.add_argument("--intel", action="store_true", help="also the whole Intel Research Lab log")
    parser.add_argument("--json")
    args = parser.parse_args()

    summaries = []
    if not args.skip_sim_structured:
        summaries += present_summary(args, "sim_structured", "sim_structured", SIM_STRUCTURED_FLAGS, args.runs)
    if not args.skip_campus:
        inputs = campus_inputs(args.campus, args.campus_scans, args.bgkmap)
        summaries.append(summarize("campus", measure(args.bgkmap, "campus", inputs, CAMPUS_FLAGS, args.campus_runs, args.threads)))
    if args.intel:
        summaries += present_summary(args, "intel", "carmen/intel-corrected.log.gz", INTEL_FLAGS, args.runs)
    if not summaries:
        sys.exit("throughput: nothing to measure (every dataset asked for is missing)")
    print_table(summaries)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summaries, f, indent=1)


if __name__ == "__main__":
    main()
