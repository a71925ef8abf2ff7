#!/usr/bin/env python3
"""Speed of the CPU path with one core taken by another process: --threads 1 vs 2, busy and quiet.

Usage: bench/busy_core.py [--bgkmap build/bgkmap] [--compare OTHER_BGKMAP] [--runs 6]
                          [--campus-runs 3] [--datasets DIR] [--campus DIR]
                          [--campus-scans 30] [--busy-core 1] [--skip-campus] [--json OUT.json]

Builds sim_structured (la3dm settings) and the first --campus-scans campus scans (the settings of
bench/throughput_table.py) with `--backend cpu` at --threads 1 and 2, quiet and with a busy loop
pinned to --busy-core (`taskset -c 1 sh -c 'while :; do :; done'`), and prints the median
insert_s of each. The configurations run interleaved: each round runs them all, every other
round in reverse order (ABBA), the busy loop started and stopped around the busy ones, so that a
slow spell of a shared machine hits every configuration alike. With --compare, the same
configurations of a second binary (e.g. an older build) run in the same rounds.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

from throughput_table import CAMPUS_FLAGS, SIM_STRUCTURED_FLAGS, build, campus_inputs
import locate  # noqa: E402  (datasets/locate.py: throughput_table puts datasets/ on the path)


class BusyLoop:
    """A shell loop spinning on one core while the `with` block runs."""

    def __init__(self, core):
        self.core = core

    def __enter__(self):
        self.proc = subprocess.Popen(["taskset", "-c", str(self.core), "sh", "-c", "while :; do :; done"])
        return self

    def __exit__(self, *exc):
        self.proc.kill()
        self.proc.wait()


def measure(binaries, inputs, flags, runs, core):
    configs = [(name, binary, load, threads) for name, binary in binaries for load in ("quiet", "busy")
               for threads in (1, 2)]
    times = {c: [] for c in configs}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(runs):
            order = configs if r % 2 == 0 else list(reversed(configs))
            for config in order:
                name, binary, load, threads = config
                flags_here = flags + ["--backend", "cpu"]
                if load == "busy":
                    with BusyLoop(core):
                        rep = build(binary, inputs, flags_here, threads, ".bgk", tmp, "busy")
                else:
                    rep = build(binary, inputs, flags_here, threads, ".bgk", tmp, "quiet")
                times[config].append(rep["timing"]["insert_s"])
                print(f"busy_core: run {r + 1}/{runs} {name} {load} threads={threads}: "
                      f"insert_s {rep['timing']['insert_s']:.3f}", file=sys.stderr)
    return times


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bgkmap", default=os.path.join(here, "..", "build", "bgkmap"))
    parser.add_argument("--compare")
    parser.add_argument("--runs", type=int, default=6)
    parser.add_argument("--campus-runs", type=int, default=3)
    parser.add_argument("--datasets", default=str(locate.datasets_dir()))
    parser.add_argument("--campus", default=os.path.join(tempfile.gettempdir(), "bgkmap-campus"))
    parser.add_argument("--campus-scans", type=int, default=30)
    parser.add_argument("--busy-core", type=int, default=1)
    parser.add_argument("--skip-campus", action="store_true")
    parser.add_argument("--json")
    args = parser.parse_args()

    binaries = [("this", args.bgkmap)] + ([("compare", args.compare)] if args.compare else [])
    datasets = []
    try:  # the datasets folder's sim_structured (datasets/locate.py), or one line saying it is missing
        datasets.append(("sim_structured", [str(locate.require("sim_structured", "busy_core", args.datasets))],
                         SIM_STRUCTURED_FLAGS, args.runs))
    except locate.Missing as missing:
        print(missing, file=sys.stderr)
    if not args.skip_campus:
        datasets.append((f"campus ({args.campus_scans} scans)", campus_inputs(args.campus, args.campus_scans, args.bgkmap),
                         CAMPUS_FLAGS, args.campus_runs))
    if not datasets:
        sys.exit("busy_core: nothing to measure (sim_structured is missing and --skip-campus was given)")
    results = []
    print("| dataset | binary | load | insert_s threads=1 | insert_s threads=2 | 2 / 1 |")
    print("|---|---|---|---|---|---|")
    for name, inputs, flags, runs in datasets:
        times = measure(binaries, inputs, flags, runs, args.busy_core)
        for binary_name, _ in binaries:
            for load in ("quiet", "busy"):
                one = statistics.median(times[(binary_name, dict(binaries)[binary_name], load, 1)])
                two = statistics.median(times[(binary_name, dict(binaries)[binary_name], load, 2)])
                print(f"| {name} | {binary_name} | {load} | {one:.3f} s | {two:.3f} s | {two / one:.2f}x |")
                results.append({"dataset": name, "binary": binary_name, "load": load, "runs": runs,
                                "insert_s_threads_1": one, "insert_s_threads_2": two})
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
