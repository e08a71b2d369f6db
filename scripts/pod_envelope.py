"""qogi.pod against the operating envelope's observed detection fractions
(issue 28, item 4): for each cell of the default grid's ``rate x
distance`` and ``contrast x wind`` blocks, the PoD curve of the scene the
cell renders (its camera, distance, contrast, record length, and the true
plume's speed and width at its middle surface), read at the cell's rate,
beside the fraction of the envelope's surfaces (every seed of the given
folders) that said "detected".

``qogi.pod`` models a steady plume at a given speed (no velocimetry, no
turbulence): the envelope's plumes fluctuate and their speed is measured,
so the comparison says how far the PoD a user is given stands from what
the full pipeline does on full plume simulations.

Usage::

    .venv/bin/python scripts/pod_envelope.py ENV_DIR [ENV_DIR ...] --seeds 4
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
from pathlib import Path


def observed(folders):
    """{(block, distance, contrast, wind, rate): [detected, ...]} over the
    folders' ok rows (a row whose rate has no decision, None, counts as not
    detected)."""
    out: dict = {}
    for folder in folders:
        with open(Path(folder) / "cells.csv", newline="") as f:
            for r in csv.DictReader(f):
                if r["status"] != "ok":
                    continue
                key = (
                    r["block"],
                    float(r["distance_m"]),
                    float(r["contrast_K"]),
                    float(r["wind_m_s"]),
                    float(r["rate_kg_h"]),
                )
                out.setdefault(key, []).append(r["detected"] == "True")
    return out


def main(argv=None) -> int:
    from qogi._progress import ProgressBar
    from qogi.apps import envelope
    from qogi.apps.detectability import PodScene, pod

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folders", nargs="+", type=Path, help="qogi envelope output folders")
    ap.add_argument("--seeds", type=int, default=4, help="PoD trials per rate")
    ap.add_argument(
        "--blocks", nargs="+", default=["rate x distance", "contrast x wind"], help="grid blocks"
    )
    a = ap.parse_args(argv)
    obs = observed(a.folders)
    cells = [c for c in envelope.load_grid("default").cells if c.block in a.blocks and c.seed == 0]
    rows = []
    bar = ProgressBar("qogi.pod per cell ")
    try:
        for k, c in enumerate(cells):
            speeds_widths = envelope.surface_truth(c)
            speed, width = speeds_widths[len(speeds_widths) // 2]
            scene = PodScene(
                camera=c.camera,
                distance_m=c.distance_m,
                delta_T_K=c.contrast_K,
                wind_speed_m_s=speed,
                plume_sigma_m=width / math.sqrt(2.0 * math.pi),
                record_s=c.duration_s,
            )
            curve = pod(scene, seeds=range(a.seeds), holdout_seeds=())
            det = obs.get((c.block, c.distance_m, c.contrast_K, c.wind_m_s, c.rate_kg_h), [])
            frac = sum(det) / len(det) if det else math.nan
            p = curve.probability(c.rate_kg_h)
            rows.append((c, speed, width, curve.stated_limit_kg_h, p, frac, len(det)))
            bar((k + 1) / len(cells), c.name)
    finally:
        bar.close()
    print(
        "| block | rate [kg/h] | distance [m] | contrast [K] | wind [m/s] | speed [m/s], "
        "width [m] | limit stated [kg/h] | qogi.pod | envelope detected (surfaces) | gap [points] |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    gaps = []
    for c, v, w, lim, p, frac, n in rows:
        gap = 100 * (frac - p) if n else math.nan
        if n:
            gaps.append(abs(gap))
        print(
            f"| {c.block} | {c.rate_kg_h:g} | {c.distance_m:g} | {c.contrast_K:+g} | "
            f"{c.wind_m_s:g} | {v:.2f}, {w:.3f} | {lim:.3g} | {100 * p:.0f} % "
            f"| {100 * frac:.0f} % ({n}) | {gap:+.0f} |"
        )
    if gaps:
        within = sum(g <= 10 for g in gaps)
        print(f"\nwithin 10 points: {within} of {len(gaps)} cells; largest gap {max(gaps):.0f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
