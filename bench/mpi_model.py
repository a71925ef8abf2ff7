#!/usr/bin/env python3
"""A model of the distributed build's time and memory per rank, fitted on measured reports.

Usage: bench/mpi_model.py RANKS_1.json RANKS_2.json [RANKS_3.json ...]
       [--predict-scans 3000 --predict-map-gb 3.3] [--bandwidth-gbs 1.25] [--latency-us 20]
       [--fs-gbs 5] [--route-ms MS]

Reads `--report` files of `mpirun -np K bgkmap build` runs (K = 1, 2, ...: bench/mpi_scaling.py's
over-K*.json, kept with --keep-reports DIR) on the same scans. From them, per scan and per core:
  t_est    the partition's estimate: reading, preparing and estimating a scan of the share
           (footprint_s / scans of the share, K = 1);
  t_read   reading and preparing a scan again for mapping (read_s / scans read);
  t_route  routing a scan to its owners (route_s / scans read; none on one rank);
  t_obs    bucketing one received observation (bucket_s / observations received);
  W        integration work of the whole map (compute_s summed over ranks, K = 1);
  s(K)     observations sent per observation read: 1 + c (sqrt(K) - 1), c fitted on K >= 2;
  t_place  rank 0's placing of the .bgk's blocks (merge_s / blocks: a K-way merge of the ranks'
           (scan, key) lists), and w, the speed at which a rank writes its records (write_map_s).
Per rank with one core:
  T(K) = N/K (t_est + t_read + t_route [K > 1] + s(K) O t_obs) + W/K + exchange + place + write
where N = scans, O = observations per scan, M = map bytes, B = blocks; exchange = the bytes a rank
receives over --bandwidth-gbs plus N/K (K - 1) messages of --latency-us (sent ahead, so latency
overlaps mapping: an upper bound); place = B t_place + 20 B bytes to rank 0 over --bandwidth-gbs;
write = the larger of M / (K w) and M over the file system's aggregate --fs-gbs. The ranks map
up to 8 rounds ahead of each other, so waiting is the imbalance of their work (not modelled:
the partition's estimate balanced pairs evaluated to 0.98-1.02x on 60 campus scans). Memory per
rank: M/K (the blocks it owns) plus the measured fixed part plus 8 rounds of observations sent
and received; rank 0 adds 24 bytes per block of the whole map while placing. Prints the fit, the
model against the measured runs, and the prediction for --predict-scans scans and a
--predict-map-gb map on 8, 32 and 128 ranks, and for the 30x larger drive (30x scans, 30x map).
"""
import argparse
import json
import math


def load(path):
    with open(path) as f:
        return json.load(f)


def per_rank_busy(p):
    return (p["footprint_s"] + p["read_s"] + p["route_s"] + p["exchange_s"] + p["insert_s"] + p.get("write_shard_s", 0)
            + p.get("write_map_s", 0))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("reports", nargs="+")
    ap.add_argument("--predict-scans", type=float, default=3000)
    ap.add_argument("--predict-map-gb", type=float, default=3.3)
    ap.add_argument("--bandwidth-gbs", type=float, default=1.25, help="network GB/s per rank (10 GbE: 1.25)")
    ap.add_argument("--latency-us", type=float, default=20, help="one message's latency")
    ap.add_argument("--fs-gbs", type=float, default=5, help="the shared file system's aggregate write GB/s")
    ap.add_argument("--route-ms", type=float, help="routing per scan, overriding the fit (a router measured apart)")
    args = ap.parse_args()
    runs = sorted((load(p) for p in args.reports), key=lambda r: r["ranks"])
    one = runs[0]
    assert one["ranks"] == 1, "the first report must be a 1-rank run"
    n = one["counts"]["scans"]
    p1 = one["per_rank"][0]
    obs = p1["observations_read"] / n
    t_read = p1["read_s"] / n
    t_est = p1["footprint_s"] / n
    t_obs = p1["bucket_s"] / p1["observations_read"]
    work = p1["compute_s"]
    blocks = p1["blocks"]
    map_gb = blocks * 4096 / 1e9
    t_place = one["timing"]["merge_s"] / blocks
    write_gbs = map_gb / p1["write_map_s"]
    routes = [sum(p["route_s"] for p in r["per_rank"]) / n for r in runs if r["ranks"] > 1]
    t_route = sum(routes) / len(routes) if routes else t_obs * obs
    if args.route_ms is not None:
        t_route = args.route_ms / 1e3
    cs = []
    for r in runs[1:]:
        s = sum(p["observations_sent"] for p in r["per_rank"]) / sum(p["observations_read"] for p in r["per_rank"])
        cs.append((s - 1) / (math.sqrt(r["ranks"]) - 1))
    c = sum(cs) / len(cs) if cs else 0.5
    base_mb = min(p["peak_rss_mb"] - p["blocks"] * 4096 / 1e6 for r in runs for p in r["per_rank"])
    print(f"fit on {n} scans: t_est {t_est * 1e3:.1f} ms, t_read {t_read * 1e3:.1f} ms, t_route {t_route * 1e3:.1f} ms, "
          f"t_obs {t_obs * 1e9:.0f} ns x {obs:.0f} observations, W {work:.1f} s ({work / n * 1e3:.0f} ms per scan), "
          f"s(K) = 1 + {c:.3f} (sqrt(K) - 1), t_place {t_place * 1e9:.0f} ns per block, write {write_gbs:.2f} GB/s, "
          f"map {map_gb:.2f} GB, fixed memory {base_mb:.0f} MB")

    def model(k, scans, gb, work_total):
        s = 1 + c * (math.sqrt(k) - 1)
        share = scans / k
        nblocks = gb * 1e9 / 4096
        read = share * (t_est + t_read)
        route = share * t_route if k > 1 else 0.0
        bucket = share * s * obs * t_obs
        compute = work_total / k
        exchange = (share * (k - 1) * args.latency_us * 1e-6 +
                    share * s * obs * 12 / (args.bandwidth_gbs * 1e9)) if k > 1 else 0.0
        place = nblocks * t_place + (nblocks * 20 / (args.bandwidth_gbs * 1e9) if k > 1 else 0.0)
        write = max(gb / k / write_gbs, gb / args.fs_gbs)
        mem = gb * 1e3 / k + base_mb + 2 * 8 * s * obs * 12 / 1e6  # 8 rounds ahead, sent and received
        busy = read + route + bucket + compute + exchange
        return {"read": read, "route": route, "bucket": bucket, "compute": compute, "exchange": exchange,
                "place": place, "write": write, "busy": busy, "total": busy + place + write, "mem_mb": mem,
                "rank0_place_mb": mem + 24 * nblocks / 1e6}

    print("\nmodel against the measured runs (per rank, max over ranks; measured on a shared machine):")
    print("| ranks | modelled busy s | measured busy s | modelled place + write s | measured place + write s | "
          "modelled total s | measured total s | modelled MB | measured peak RSS MB |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in runs:
        k = r["ranks"]
        m = model(k, n, map_gb, work)
        busy = max(per_rank_busy(p) - p.get("write_map_s", 0) for p in r["per_rank"])
        print(f"| {k} | {m['busy']:.1f} | {busy:.1f} | {m['place'] + m['write']:.1f} | "
              f"{r['timing']['merge_s'] + r['timing']['write_s']:.1f} | {m['total']:.1f} | {r['timing']['total_s']:.1f} | "
              f"{m['mem_mb']:.0f} | {max(p['peak_rss_mb'] for p in r['per_rank']):.0f} |")
    for label, scans, gb in (("campus", args.predict_scans, args.predict_map_gb),
                             ("30x drive", 30 * args.predict_scans, 30 * args.predict_map_gb)):
        print(f"\n{label}: {scans:.0f} scans, {gb:.0f} GB map, one core per rank "
              f"(integration work scaled from the fit: {work * scans / n / 3600:.1f} core-hours)")
        print("| ranks | estimate + reading | routing | bucketing received | integration | exchange | "
              "placing (rank 0) | writing the .bgk | total | memory per rank | rank 0 while placing |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for k in (1, 8, 32, 128):
            m = model(k, scans, gb, work * scans / n)
            print(f"| {k} | {m['read']:.0f} s | {m['route']:.0f} s | {m['bucket']:.0f} s | {m['compute']:.0f} s | "
                  f"{m['exchange']:.1f} s | {m['place']:.1f} s | {m['write']:.1f} s | {m['total']:.0f} s | "
                  f"{m['mem_mb'] / 1e3:.2f} GB | {m['rank0_place_mb'] / 1e3:.2f} GB |")


if __name__ == "__main__":
    main()
