#!/usr/bin/env python3
"""Strong scaling of the distributed build (mpirun -np K bgkmap build) on one machine.

Usage: bench/mpi_scaling.py [--bgkmap build/bgkmap] [--campus DIR] [--scans 100] [--rounds 2]
                            [--max-ranks 4] [--mpirun mpirun] [--json OUT.json] [--keep-reports DIR]

Builds the first --scans campus scans (the settings of bench/throughput_table.py, CPU path, one
thread per rank, -o X.bgk: the ranks write it together, no shards kept) as
  single   `bgkmap build --threads 1`            (no mpirun)
  single2  `bgkmap build --threads 2`            (the single-process build on both cores)
  K1, K2   `mpirun -np 1|2 bgkmap build --threads 1`
interleaved: each round runs them all, every other round in reverse order (ABBA), so that a slow
spell of a shared machine hits every configuration alike; then K = 1..--max-ranks with
--oversubscribe (one round). Prints medians of the wall time, the parallel efficiency of 2 ranks
(T_single,1 thread / (2 T_2 ranks), the issue's figure; and against one rank and the single
process on 2 threads), per-rank stage times from the report (estimate, read, route, exchange,
wait, insert, placing and writing the .bgk), pairs evaluated per rank, bytes exchanged per scan
and peak RSS per rank, and the load average before each run. The first run of each
configuration checks that the .bgk is the single-process one (SHA-256).
"""
import argparse
import hashlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from throughput_table import CAMPUS_FLAGS, campus_inputs

MPI_ENV = {"OMPI_MCA_btl_vader_single_copy_mechanism": "none", "OMPI_MCA_mpi_yield_when_idle": "1",
           "OMPI_ALLOW_RUN_AS_ROOT": "1",
           "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1"}


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def run(args, config, inputs, tmp, tag, check_map):
    ranks, threads, oversubscribe = config
    report = os.path.join(tmp, tag + ".json")
    out = os.path.join(tmp, tag + ".bgk")
    flags = ["build", "-q", *inputs, *CAMPUS_FLAGS, "--backend", "cpu", "--threads", str(threads), "--report", report]
    if ranks == 0:
        cmd = [args.bgkmap, *flags, "-o", out]
    else:
        cmd = [args.mpirun, "-np", str(ranks), *(["--oversubscribe"] if oversubscribe else []), args.bgkmap, *flags,
               "-o", out]
    load = os.getloadavg()[0]
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, env={**os.environ, **MPI_ENV})
    wall = time.monotonic() - t0
    with open(report) as f:
        rep = json.load(f)
    if args.keep_reports:
        os.makedirs(args.keep_reports, exist_ok=True)
        shutil.copy(report, os.path.join(args.keep_reports, tag + ".json"))
    digest = None
    if check_map:
        digest = sha256(out)
    if os.path.exists(out):
        os.remove(out)
    row = {"wall_s": wall, "load": load, "total_s": rep["timing"]["total_s"], "sha256": digest}
    if ranks > 0:
        per = rep["per_rank"]
        scans = rep["counts"]["scans"]
        for key in ("read_s", "route_s", "exchange_s", "wait_s", "insert_s", "footprint_s", "write_map_s"):
            row[key] = max(p[key] for p in per)
        row["pairs_evaluated"] = [p["pairs_evaluated"] for p in per]
        row["wait_per_rank_s"] = [p["wait_s"] for p in per]
        row["merge_s"] = rep["timing"]["merge_s"]
        row["write_s"] = rep["timing"]["write_s"]
        row["bytes_sent_per_scan"] = sum(p["bytes_sent"] for p in per) / scans
        row["observations_sent_per_scan"] = sum(p["observations_sent"] for p in per) / scans
        row["observations_read_per_scan"] = sum(p["observations_read"] for p in per) / scans
        row["peak_rss_mb"] = [p["peak_rss_mb"] for p in per]
        row["blocks"] = [p["blocks"] for p in per]
        row["insert_per_rank_s"] = [p["insert_s"] for p in per]
        row["estimated_cost"] = [p["estimated_cost"] for p in per]
    else:
        row["insert_s"] = rep["timing"]["insert_s"]
        row["read_s"] = rep["timing"].get("read_s")
        row["write_s"] = rep["timing"]["write_s"]
        row["peak_rss_mb"] = [rep.get("peak_rss_mb")]
    print(f"mpi_scaling: {tag}: wall {wall:.2f} s, load {load:.1f}", file=sys.stderr)
    return row


def median_row(rows):
    out = {}
    for key in rows[0]:
        values = [r[key] for r in rows]
        if isinstance(values[0], (int, float)) and values[0] is not None:
            out[key] = statistics.median(values)
        else:
            out[key] = values[0]
    out["wall_all_s"] = [r["wall_s"] for r in rows]
    out["load_all"] = [r["load"] for r in rows]
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bgkmap", default="build/bgkmap")
    p.add_argument("--mpirun", default="mpirun")
    p.add_argument("--campus", default="/tmp/campus")
    p.add_argument("--scans", type=int, default=100)
    p.add_argument("--rounds", type=int, default=2)
    p.add_argument("--max-ranks", type=int, default=4)
    p.add_argument("--json")
    p.add_argument("--keep-reports", help="copy every run's --report here (for bench/mpi_model.py)")
    args = p.parse_args()
    inputs = campus_inputs(args.campus, args.scans, args.bgkmap)
    strong = {"single": (0, 1, False), "single2": (0, 2, False), "K1": (1, 1, False), "K2": (2, 1, False)}
    results = {name: [] for name in strong}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            order = list(strong) if r % 2 == 0 else list(reversed(strong))
            for name in order:
                results[name].append(run(args, strong[name], inputs, tmp, f"{name}-{r}", check_map=(r == 0)))
        over = {}
        for k in range(1, args.max_ranks + 1):
            over[f"K{k}"] = run(args, (k, 1, True), inputs, tmp, f"over-K{k}", check_map=True)
    summary = {"scans": args.scans, "cores": os.cpu_count(), "strong": {n: median_row(v) for n, v in results.items()},
               "oversubscribed": over}
    digests = {n: v[0]["sha256"] for n, v in results.items()} | {f"over-{n}": v["sha256"] for n, v in over.items()}
    summary["same_map"] = len(set(digests.values())) == 1
    summary["map_sha256"] = sorted(set(digests.values()))
    s = summary["strong"]
    print(f"{args.scans} campus scans, medians of {args.rounds} ABBA rounds (wall s):")
    for name in strong:
        print(f"  {name:8s} {s[name]['wall_s']:.2f}  (all {', '.join(f'{w:.2f}' for w in s[name]['wall_all_s'])};"
              f" load {', '.join(f'{l:.1f}' for l in s[name]['load_all'])})")
    eff = {"single": s["single"]["wall_s"] / (2 * s["K2"]["wall_s"]), "K1": s["K1"]["wall_s"] / (2 * s["K2"]["wall_s"]),
           "single2": s["single2"]["wall_s"] / s["K2"]["wall_s"],
           "single2_threads": s["single"]["wall_s"] / (2 * s["single2"]["wall_s"])}
    summary["efficiency"] = eff
    print(f"  parallel efficiency of 2 ranks, T_single(1 thread) / (2 T_2 ranks): {eff['single']:.0%} (goal >= 70 %)")
    print(f"  against one rank, T_1 rank / (2 T_2 ranks): {eff['K1']:.0%}")
    print(f"  against the single process on 2 threads: T_single(2 threads) / T_2 ranks = {eff['single2']:.2f}x"
          f" (that process's own efficiency on 2 threads: {eff['single2_threads']:.0%})")
    k2 = s["K2"]
    print(f"  2 ranks, max over ranks: estimate {k2['footprint_s']:.2f} s, read {k2['read_s']:.2f}, route {k2['route_s']:.2f},"
          f" exchange {k2['exchange_s']:.2f}, wait {k2['wait_s']:.2f}, insert {k2['insert_s']:.2f}"
          f" (per rank {', '.join(f'{v:.2f}' for v in k2['insert_per_rank_s'])}), placing the .bgk {k2['merge_s']:.2f},"
          f" writing it {k2['write_s']:.2f}; pairs evaluated per rank {', '.join(f'{v:.3g}' for v in k2['pairs_evaluated'])}")
    for name, row in over.items():
        print(f"  oversubscribed {name}: wall {row['wall_s']:.2f} s, read {row['read_s']:.2f}, route {row['route_s']:.2f},"
              f" exchange {row['exchange_s']:.2f}, wait {row['wait_s']:.2f}, place {row['merge_s']:.2f}, write {row['write_s']:.2f},"
              f" insert {row['insert_s']:.2f} (per rank {row['insert_per_rank_s']}),"
              f" {row['bytes_sent_per_scan'] / 1e6:.3f} MB sent per scan, peak RSS {row['peak_rss_mb']} MB")
    print(f"  same map in every configuration: {summary['same_map']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(summary, f, indent=1)


if __name__ == "__main__":
    main()
