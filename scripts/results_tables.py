#!/usr/bin/env python3
"""Markdown tables of scripts/results.sh's run: one per dataset, one row per method.

Usage: results_tables.py [--without-sim-structured] OUT_DIR METHOD...   (scripts/results.sh; the flag
                                        when the datasets folder had no sim_structured)
       results_tables.py --real OUT_DIR DATASET...   (scripts/real_data.sh: the methods its eval scored)
Reads OUT_DIR/<dataset>/eval.json (bgkmap eval) and OUT_DIR/<dataset>/<method>.report.json
(bgkmap build --report) and prints the tables to stdout.
"""
import json
import os
import sys


def load(path):
    with open(path) as f:
        return json.load(f)


def fixed(value, digits=4):
    return "n/a" if value is None else f"{value:.{digits}f}"


def count(value):
    return f"{value:,}"


def build_columns(report):
    t = report["timing"]
    return [fixed(t["insert_s"], 2), fixed(t["total_s"], 2), f"{report['peak_rss_mb']:.0f}",
            count(report["counts"]["cells_with_evidence"])]


BUILD_HEADER = ["insert s", "total s", "peak MB", "cells with evidence"]


def table(header, rows):
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(row) + " |" for row in rows]
    return "\n".join(lines)


def truth_table(out, dataset, methods):
    evaluation = load(os.path.join(out, dataset, "eval.json"))
    by_map = {os.path.splitext(os.path.basename(m["map"]))[0]: m for m in evaluation["maps"]}
    rows = []
    for method in methods:
        protocols = by_map[method]["protocols"]
        a, o = protocols["all_cells"], protocols["observed_cells"]
        report = load(os.path.join(out, dataset, method + ".report.json"))
        rows.append([method, fixed(a["auc"]), fixed(a["average_precision"]), fixed(a["nll"]),
                     fixed(o["auc"]), fixed(o["average_precision"]), fixed(o["nll"]),
                     count(o["n_positive"] + o["n_negative"])] + build_columns(report))
    a = evaluation["maps"][0]["protocols"]["all_cells"]
    box = evaluation["evaluated_box"]
    corner = lambda c: " ".join(f"{v:.1f}" for v in c)
    caption = (f"**{dataset}** (all cells: {count(a['n_positive'])} occupied + {count(a['n_negative'])} free, "
               f"in the box {corner(box['min'])} .. {corner(box['max'])} m)")
    header = ["method", "AUC (all)", "AP (all)", "NLL (all)", "AUC (obs.)", "AP (obs.)", "NLL (obs.)",
              "cells scored (obs.)"] + BUILD_HEADER
    return caption + "\n\n" + table(header, rows)


def holdout_table(out, dataset, methods):
    evaluation = load(os.path.join(out, dataset, "eval.json"))
    by_method = {m["method"]: m for m in evaluation["methods"]}
    rows = []
    for method in methods:
        m = by_method[method]
        report = load(os.path.join(out, dataset, method + ".report.json"))
        rows.append([method, fixed(m["auc"]), fixed(m["average_precision"]), fixed(m["nll"]),
                     fixed(m["accuracy"]), fixed(m["occupied_threshold"], 2)] + build_columns(report))
    h = evaluation["holdout"]
    first = evaluation["methods"][0]
    total_beams = count(h["held_out_beams"] + h["kept_beams"])
    if h.get("split") == "scans":
        held = (f"whole scans in runs of {h['run_length']}, fraction {h['fraction']}, seed {h['seed']}: "
                f"{count(h['held_out_scans'])} of {count(h['scans'])} scans, {count(h['held_out_beams'])} of "
                f"{total_beams} beams held out")
        title = f"**{dataset}, held-out scans**"
    else:
        held = (f"fraction {h['fraction']}, seed {h['seed']}: {count(h['held_out_beams'])} of {total_beams} "
                "beams held out")
        title = f"**{dataset}, held-out beams**"
    caption = (f"{title} ({held}; {count(first['n_positive'])} occupied and {count(first['n_negative'])} free "
               "samples; build columns: all scans, same flags)")
    header = ["method", "AUC", "AP", "NLL", "accuracy", "at threshold"] + BUILD_HEADER
    return caption + "\n\n" + table(header, rows)


def machine_line(out):
    with open(os.path.join(out, "machine.txt")) as f:
        return "Build times measured on " + ", ".join(line.strip() for line in f if line.strip()) + "."


def main():
    if len(sys.argv) >= 3 and sys.argv[1] == "--real":
        out, datasets = sys.argv[2], sys.argv[3:]
        parts = []
        for dataset in datasets:
            scored = [m["method"] for m in load(os.path.join(out, dataset, "eval.json"))["methods"]]
            parts.append(holdout_table(out, dataset, scored))
        parts.append(machine_line(out))
        print("\n\n".join(parts))
        return
    args = sys.argv[1:]
    with_sim_structured = not (args and args[0] == "--without-sim-structured")
    args = args if with_sim_structured else args[1:]
    if len(args) < 2:
        sys.exit(__doc__)
    out, methods = args[0], args[1:]
    parts = [truth_table(out, "structured", methods), truth_table(out, "unstructured", methods)]
    if with_sim_structured:
        parts.append(holdout_table(out, "sim_structured", methods))
    parts.append(machine_line(out))
    print("\n\n".join(parts))


if __name__ == "__main__":
    main()
