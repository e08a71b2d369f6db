"""The probability-of-detection table of docs/detection_limit.md (issue 28,
item 4): ``qogi.pod`` for the GF320 and the FAST M150 at the scenes the
regulations name, fitted on seeds 0-5 and checked on held-out seeds
1000-1005.

Scenes:

* ``EPA``: the EPA OGI camera-sensitivity point, 2 m, delta-T 5 K, wind
  1 m/s, a plume of sigma 5 cm at the surface;
* ``far``: 30 m, delta-T 5 K, wind 3 m/s, a plume of sigma 0.3 m (at 0.5 m
  the pipeline estimated a depth beyond its tables' 2 m and stopped with a
  ValueError);

each with 30 frames of record (2 s at the GF320's 15 Hz, 0.3 s at the FAST
M150's 100 Hz: the M150's multichannel inversion costs ~60 s per 200-frame
trial here).

Per scene: the limit qogi states, the rates detected with 50 and 90 %
probability, the false-alarm rate, the PoD at the regulations' rates (EPA
19 g/h, EU 1 and 17 g/h; OOOOb's 1, 2, 5, 10, 15 kg/h tiers for the far
scene) and the largest gap between the observed held-out detection fraction
and the fitted curve. Writes the JSON of every curve and prints markdown.

Usage::

    .venv/bin/python scripts/pod_table.py --out /tmp/pod.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

SCENES = {
    "EPA": dict(distance_m=2.0, delta_T_K=5.0, wind_speed_m_s=1.0, plume_sigma_m=0.05),
    "far": dict(distance_m=30.0, delta_T_K=5.0, wind_speed_m_s=3.0, plume_sigma_m=0.3),
}
CAMERAS = ("gf320", "fast-m150")
#: Record length [s] per camera: 30 frames each.
RECORD_S = {"gf320": 2.0, "fast-m150": 0.3}
#: Rates [g/h] the table states the PoD at, per scene.
AT_G_H = {"EPA": (1.0, 17.0, 19.0), "far": (1e3, 2e3, 5e3, 1e4, 1.5e4)}


def main(argv=None) -> int:
    from qogi._progress import ProgressBar
    from qogi.apps.detectability import PodScene, pod

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6)
    ap.add_argument("--holdout-seeds", type=int, default=6)
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--cameras", nargs="+", default=list(CAMERAS), choices=list(CAMERAS))
    ap.add_argument("--out", type=Path, help="write every curve as JSON")
    ap.add_argument(
        "--refit",
        type=Path,
        help="no trials: refit the curves of a JSON this script wrote (its per-rate counts)",
    )
    a = ap.parse_args(argv)
    curves = _refit(a.refit) if a.refit else {}
    for name in a.scenes if not a.refit else ():
        for cam in a.cameras:
            scene = PodScene(camera=cam, record_s=RECORD_S[cam], **SCENES[name])
            bar = ProgressBar(f"{name} {cam} ")
            try:
                c = pod(
                    scene,
                    seeds=range(a.seeds),
                    holdout_seeds=range(1000, 1000 + a.holdout_seeds),
                    progress=bar,
                )
            finally:
                bar.close()
            curves[(name, cam)] = c
            if a.out:
                a.out.write_text(
                    json.dumps({f"{k[0]} {k[1]}": v.to_dict() for k, v in curves.items()}, indent=1)
                )
    lines = [
        "| scene | camera | limit stated [g/h] | PoD 50 % [g/h] | PoD 90 % [g/h] "
        "| 90 % / stated | false alarms | PoD at | held-out: largest gap (its binomial sigma) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for (name, cam), c in curves.items():
        at = ", ".join(f"{q:g} g/h {100 * c.probability(q / 1e3):.0f} %" for q in AT_G_H[name])
        rows = [r for r in c.table("holdout") if r["rate_kg_h"] > 0]
        worst = max(rows, key=lambda r: abs(r["observed"] - r["fitted"]), default=None)
        gap = None if worst is None else abs(worst["observed"] - worst["fitted"])
        sig = (
            0.0 if worst is None else (worst["fitted"] * (1 - worst["fitted"]) / worst["n"]) ** 0.5
        )
        lines.append(
            f"| {name} | {cam} | {c.stated_limit_kg_h * 1e3:.3g} | {c.q50_kg_h * 1e3:.3g} | "
            f"{c.rate_at(0.9) * 1e3:.3g} | {c.rate_at(0.9) / c.stated_limit_kg_h:.2f} | "
            f"{'-' if c.false_alarm is None else f'{100 * c.false_alarm:.0f} %'} | {at} | "
            f"{'-' if gap is None else f'{100 * gap:.0f} points ({100 * sig:.0f})'} |"
        )
    print("\n".join(lines))
    for (name, cam), c in curves.items():
        print(f"\n{name} {cam} held-out (rate g/h: observed / fitted):")
        print(
            ", ".join(
                f"{r['rate_kg_h'] * 1e3:.3g}: {100 * r['observed']:.0f} / {100 * r['fitted']:.0f} %"
                for r in c.table("holdout")
            )
        )
    return 0


def _refit(path: Path) -> dict:
    """The curves of a JSON written with --out, refitted (qogi.apps.detectability's
    current fit) from its per-rate counts."""
    from qogi.apps.detectability import PodCurve, PodScene, Trial, fit_logistic

    out = {}
    for key, d in json.loads(path.read_text()).items():
        name, cam = key.split(" ", 1)

        def trials(rows):
            ts = []
            for r in rows:
                k = round(r["observed"] * r["n"])
                ts += [Trial(r["rate_kg_h"], -1, i < k, float("nan"), None) for i in range(r["n"])]
            return ts

        fit, held = trials(d["fit"]), trials(d["holdout"])
        q50, s = fit_logistic([t.rate_kg_h for t in fit], [t.detected for t in fit])
        out[(name, cam)] = PodCurve(
            PodScene(**d["scene"]), q50, s, fit, held, d["false_alarm"], d["stated_limit_kg_h"]
        )
    return out


if __name__ == "__main__":
    sys.exit(main())
