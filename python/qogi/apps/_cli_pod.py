"""``qogi pod``: the probability of detection of a scene (qogi.apps.detectability)."""

from __future__ import annotations

import argparse
import json
import sys

from .._progress import ProgressBar
from ..errors import UsageError
from ..files import atomic_open, atomic_path, check_outputs
from ..io.open import open_recording
from ._cli_args import finite_float, nonnegative_float, nonnegative_int, positive_float
from .detectability import POD_LEVEL, PodScene, pod, recording_min_detectable_column


def _table(curve, which: str) -> str:
    rows = curve.table(which)
    lines = [
        f"  {'rate [g/h]':>11s} {'trials':>6s} {'detected':>9s} {'fitted PoD':>10s}",
    ]
    for r in rows:
        lines.append(
            f"  {r['rate_kg_h'] * 1e3:11.4g} {r['n']:6d} {100 * r['observed']:8.0f}% "
            f"{100 * r['fitted']:9.0f}%"
        )
    return "\n".join(lines)


#: The scene's options: PodScene field -> (flag, type, metavar, help with
#: the default's place); the defaults are PodScene's (declared once, there).
_SCENE_OPTIONS = {
    "camera": ("--camera", None, None, "camera preset (default {})"),
    "distance_m": ("--distance", positive_float, "M", "camera to plume (default {:g} m)"),
    "delta_T_K": (
        "--delta-t",
        finite_float,
        "K",
        "gas minus background temperature (negative: absorption; default {:g} K)",
    ),
    "wind_speed_m_s": (
        "--wind-speed",
        positive_float,
        "M_S",
        "gas speed across the surface (default {:g} m/s)",
    ),
    "plume_sigma_m": (
        "--plume-sigma",
        positive_float,
        "M",
        "the plume's standard deviation across the surface (default {:g} m)",
    ),
    "record_s": ("--record", positive_float, "S", "record length (default {:g} s)"),
    "ambient_temperature_K": (
        "--ambient-temperature",
        positive_float,
        "K",
        "air and gas temperature (default {:g} K)",
    ),
    "species": ("--species", None, None, "default {}"),
    "netd_K": ("--netd", positive_float, "K", "camera noise (preset's)"),
}


def cmd_map(args: argparse.Namespace) -> int:
    """``qogi pod --map REC``: the recording's minimum-detectable column map."""
    import numpy as np

    out = args.map_out
    if out is not None:
        check_outputs({"--map-out": out}, inputs=[args.map])
        if not out.lower().endswith((".npy", ".png")):
            raise UsageError(f"--map-out {out}: give a .npy or .png file name")
    with open_recording(args.map) as rec:
        mdc, _ = recording_min_detectable_column(rec)
    finite = mdc[np.isfinite(mdc)]
    g = 1e3  # g/m2
    print(
        f"qogi pod --map {args.map}: minimum-detectable column (k + z) NEC per pixel "
        f"[g/m2]: median {np.median(finite) * g:.3g}, 5-95 % "
        f"{np.percentile(finite, 5) * g:.3g} .. {np.percentile(finite, 95) * g:.3g}"
        + (f"; {mdc.size - finite.size} pixels without contrast" if finite.size < mdc.size else "")
        if finite.size
        else f"qogi pod --map {args.map}: no pixel has contrast with the gas"
    )
    if out is None:
        return 0
    with atomic_path(out, suffix=out[-4:]) as tmp:
        if out.lower().endswith(".npy"):
            with open(tmp, "wb") as fh:
                np.save(fh, mdc.astype(np.float32))
        else:
            import matplotlib

            matplotlib.use("Agg", force=False)
            import matplotlib.pyplot as plt

            fig, ax = plt.subplots(figsize=(6.4, 4.8))
            im = ax.imshow(mdc * g, cmap="viridis")
            fig.colorbar(im, ax=ax, label="minimum-detectable column [g/m2]")
            ax.set_title("(k + z) x noise-equivalent column per pixel")
            fig.tight_layout()
            fig.savefig(tmp, dpi=100)
            plt.close(fig)
    print(f"wrote {out}")
    return 0


def cmd_pod(args: argparse.Namespace) -> int:

    if args.map is not None:
        return cmd_map(args)
    if args.json and args.json != "-":
        check_outputs({"--json": args.json})
    scene = PodScene(**{name: getattr(args, name) for name in _SCENE_OPTIONS})
    if args.seeds < 1:
        raise UsageError("--seeds must be at least 1 (the trials the curve is fitted on)")
    rates = None if args.rates is None else [q / 1e3 for q in args.rates]
    bar = ProgressBar("pod ", enabled=not args.quiet)
    try:
        curve = pod(
            scene,
            rates_kg_h=rates,
            seeds=range(args.seeds),
            holdout_seeds=range(1000, 1000 + args.holdout_seeds),
            progress=bar,
        )
    finally:
        bar.close()
    d = curve.to_dict()
    if args.json:
        text = json.dumps(d, indent=2)
        if args.json == "-":
            print(text)
        else:
            with atomic_open(args.json, "w") as fh:
                fh.write(text + "\n")
    out = sys.stderr if args.json == "-" else sys.stdout
    if not args.quiet or args.json != "-":
        pct = int(round(100 * POD_LEVEL))
        print(
            f"qogi pod: {scene.species}, {scene.camera} at {scene.distance_m:g} m, "
            f"delta-T {scene.delta_T_K:+g} K, {scene.wind_speed_m_s:g} m/s, plume sigma "
            f"{scene.plume_sigma_m:g} m, {scene.record_s:g} s\n"
            f"  detected with {pct} % probability: {curve.rate_at(POD_LEVEL) * 1e3:.3g} g/h "
            f"(50 %: {curve.q50_kg_h * 1e3:.3g} g/h); limit qogi states: "
            f"{curve.stated_limit_kg_h * 1e3:.3g} g/h\n"
            + (
                f"  false alarms (rate 0): {100 * curve.false_alarm:.0f} %\n"
                if curve.false_alarm is not None
                else ""
            )
            + (
                ""
                if scene.speed_measurable
                else f"  an upper bound: the gas moves {scene.flow_displacement_px:.3g} px "
                f"between the flow's frames (its range is 1-64 px), so qogi is not expected "
                f"to measure its speed here; this PoD gave it the speed\n"
            )
            + f"fitted on seeds 0..{args.seeds - 1}:\n"
            + _table(curve, "fit")
            + (
                f"\nchecked on {args.holdout_seeds} held-out seeds:\n" + _table(curve, "holdout")
                if curve.holdout
                else ""
            ),
            file=out,
        )
    return 0


def add_commands(sub) -> None:
    import dataclasses

    # The scene's defaults are PodScene's (declared once, there).
    d = {f.name: f.default for f in dataclasses.fields(PodScene)}
    p = sub.add_parser(
        "pod",
        help="probability of detection of a scene (a PoD curve and the rate detected at 90 %%)",
        description="Render steady releases of known rate in the scene (the camera's noise, "
        "the forward model), quantify each with the given gas speed and count how often "
        "qogi says 'detected'; fit a logistic curve in the log of the rate and print the "
        "rate detected with 90 % probability, the false-alarm rate and the observed "
        "detection fractions on held-out seeds against the curve (docs/detection_limit.md). "
        "The default run is 56-72 small quantifications (5-10 minutes with a GF320 here).",
    )
    for name, (flag, kind, metavar, text) in _SCENE_OPTIONS.items():
        p.add_argument(
            flag, dest=name, type=kind, default=d[name], metavar=metavar, help=text.format(d[name])
        )
    p.add_argument(
        "--rates",
        type=nonnegative_float,
        nargs="+",
        metavar="G_H",
        help="release rates [g/h] (default: 0 and the stated limit x 0.71, 1, 1.41, 2, 2.83, 4)",
    )
    p.add_argument("--seeds", type=nonnegative_int, default=4, help="seeds fitted on (4)")
    p.add_argument(
        "--holdout-seeds", type=nonnegative_int, default=4, help="held-out seeds checked (4)"
    )
    p.add_argument("--json", metavar="OUT.json|-", help="write the curve and tables as JSON")
    p.add_argument(
        "--map",
        metavar="REC",
        help="instead: the minimum-detectable column per pixel of a recording (its "
        "background's temperature, the camera's NETD, the gas at ambient)",
    )
    p.add_argument("--map-out", metavar="OUT.npy|OUT.png", help="write the --map (kg/m2 in .npy)")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_pod)
