#!/usr/bin/env python3
"""Map a folder of scans from Python, query it, score it and write it for octovis.

Usage: python3 examples/python_quickstart.py SCANS_FOLDER OUT_DIR
(e.g. ../shared/datasets/sim_structured, or the scans/ folder of `bgkmap simulate structured`).
"""
import pathlib
import sys

import numpy as np

import bgkmap


def main(scans, out):
    out.mkdir(parents=True, exist_ok=True)
    m = bgkmap.Mapper(resolution=0.1, ell=0.2, ds=0.1, max_range=8)
    print(f"{m.insert_file(scans)} scans on {m.backend['name']} ({m.backend['device']})")

    centres, alpha, beta = m.cells()
    mean = alpha / (alpha + beta)
    print(f"{len(alpha)} cells with evidence, {np.sum(m.state(centres) == bgkmap.OCCUPIED)} occupied")

    # Hold-out style check: do the map's probabilities separate hit cells from the free space
    # along a beam? Hits of the last scan are "occupied", points halfway to them "free".
    last = bgkmap.read_scans(scans)[-1]
    hits = last["points"][np.isfinite(last["points"]).all(axis=1)].astype(np.float64)
    halfway = (hits + last["origin"]) / 2
    labels = np.r_[np.ones(len(hits), int), np.zeros(len(halfway), int)]
    scores = m.mean(np.vstack([hits, halfway]))
    print(f"AUC hits vs. halfway points: {bgkmap.auc(labels, scores):.3f}")

    m.save(str(out / "map.bgk"))
    m.export(str(out / "map.ot"))
    report = bgkmap.build(scans, method="octomap", outputs=[str(out / "octomap.ot")], max_range=8)
    print(f"octomap: {report['counts']['cells_with_evidence']} known cells; mean occupancy of BGK-L cells "
          f"{mean.mean():.3f}")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(pathlib.Path(sys.argv[1]), pathlib.Path(sys.argv[2]))
