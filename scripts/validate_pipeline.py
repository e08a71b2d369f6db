"""End-to-end validation of the pipeline on synthetic releases with exact truth
(docs/validation.md): recording -> column densities -> velocities -> emission
rate with its 90 % interval, against the simulation's exact release rate.

Cases (each over seeds 0..N-1; recordings are cached under --cache):

* ``m150``: lab-ch4co2-90c-m150 (50/50 CH4/CO2 at 90 C, four channels, 100 Hz),
  gas temperature inferred, composition known, the default velocimetry;
* ``gf320``: lab-ch4-5slpm-gf320 (CH4 at ambient, one channel, 15 Hz), gas
  temperature ambient (it is), the default velocimetry;
* ``heated-1ch``: lab-heated-ch4-55c-gf320 quantified single channel with the
  gas temperature assumed ambient (what a single-channel tool does);
* ``heated-4ch``: the same release rendered through the four-channel
  fast-m150 camera (same pixel footprint), gas temperature inferred;
* ``wind``: stack-20kgh-wind6-gf320 (20 kg/h CH4 from a 3.18 m stack in a
  6 m/s crosswind, GF320 at 10 m against the sky, 15 Hz: the gas crosses
  ~28 px per frame), vertical surfaces 50, 100, 150 px downwind;
* ``sky``: stack-10kgh-wind4-sky-gf320 (10 kg/h CH4, 4 m/s crosswind with
  20 % turbulence, a clear sky from 250 K at the top to 265 K at the bottom,
  gas 288 K), vertical surfaces 0.5, 1.0, 1.5 m downwind, defaults;
* ``cross-rule``: lab-ch4-5slpm-gf320 rendered with the line shape
  ``hapi+air`` (HAPI's wings, air broadening) and quantified with qogi's
  default ``fixed:25+self``: the line-shape term must cover the difference;
* ``heated-1ch-exit``: the heated-1ch recording with the exit temperature
  (328.15 K) given: the gas-temperature-suspect warning's evidence;
* ``laminar``: lab-ch4-5slpm-laminar-gf320 (the same release as a quiet,
  nearly laminar column accelerating as it rises, with a speed wave slower
  than the gas; GF320-like at 100 Hz, 3 s), defaults, only the source given;
* ``textured-lab``: lab-ch4-5slpm-textured-gf320 (the gf320 release in front
  of a plate with a 0.3 K RMS texture), defaults, only the source given;
* ``textured-sky``, ``clouds``, ``wall-absorption``, ``tank-emission``,
  ``piperack``: the scenes with structure (:data:`STRUCTURED`), vertical
  surfaces 0.5, 1.0, 1.5 m downwind (to the left where the wind blows so).

Control surfaces (lab cases): horizontal lines 100 px wide (m150) or 80 px
(GF320) centred on the exit at the truth's control-plane rows up to 12 cm
above the exit; the exit is given as the source (flow away from it is
positive).

Usage:
    .venv/bin/python scripts/validate_pipeline.py --seeds 10 [--cases m150 gf320 ...]
    .venv/bin/python scripts/validate_pipeline.py --report   # tables and plots from the cache
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

import qogi
from qogi.diagnostics import Diagnostics
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import Surface, auto_surfaces, plume_image, truth_surfaces
from qogi.synth import render

CASES = {
    "m150": dict(
        preset="lab-ch4co2-90c-m150",
        camera=None,
        duration_s=2.0,
        gas_temperature="infer",
        composition={"CH4": 0.5, "CO2": 0.5},
    ),
    "gf320": dict(
        preset="lab-ch4-5slpm-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
    ),
    "heated-1ch": dict(
        preset="lab-heated-ch4-55c-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
    ),
    "heated-4ch": dict(
        preset="lab-heated-ch4-55c-gf320",
        camera="fast-m150",
        duration_s=2.0,
        gas_temperature="infer",
        composition=None,
    ),
    "wind": dict(
        preset="stack-20kgh-wind6-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
    ),
    "sky": dict(
        preset="stack-10kgh-wind4-sky-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
    ),
    "cross-rule": dict(
        preset="lab-ch4-5slpm-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
        render_line_shape="hapi+air",
    ),
    "heated-1ch-exit": dict(
        preset="lab-heated-ch4-55c-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
        recording="heated-1ch",
        exit_temperature_K=328.15,
    ),
    "laminar": dict(
        preset="lab-ch4-5slpm-laminar-gf320",
        camera=None,
        duration_s=3.0,
        gas_temperature="ambient",
        composition=None,
    ),
    "textured-lab": dict(
        preset="lab-ch4-5slpm-textured-gf320",
        camera=None,
        duration_s=10.0,
        gas_temperature="ambient",
        composition=None,
    ),
}
#: The scenes with structure (issue 31; docs/synthetic.md): crosswind
#: stacks as ``sky`` against textured skies, drifting clouds, walls seen in
#: absorption and emission, a pipe rack; defaults, only the source given.
STRUCTURED = {
    "textured-sky": "stack-10kgh-wind4-textured-sky-gf320",
    "clouds": "stack-10kgh-wind4-clouds-gf320",
    "wall-absorption": "stack-3kgh-wind3-wall-absorption-gf320",
    "tank-emission": "stack-5kgh-wind3-tank-emission-gf320",
    "piperack": "stack-10kgh-wind4-piperack-gf320",
}
for _case, _preset in STRUCTURED.items():
    CASES[_case] = dict(
        preset=_preset, camera=None, duration_s=10.0, gas_temperature="ambient", composition=None
    )
#: Downwind distances [px] of the vertical surfaces of the crosswind cases.
WIND_DISTANCES_PX = {
    "wind": (50, 100, 150),
    # 0.5, 1.0, 1.5 m at 1.309 cm per pixel
    "sky": (38, 76, 115),
    **dict.fromkeys(STRUCTURED, (38, 76, 115)),
}
MAX_HEIGHT_M = 0.125


def recording_path(cache: Path, case: str, seed: int) -> Path:
    c = CASES[case]
    return cache / f"{c.get('recording', case)}-{c['duration_s']:g}s-seed{seed}.h5"


def ensure_recording(cache: Path, case: str, seed: int) -> Path:
    path = recording_path(cache, case, seed)
    if not path.exists():
        c = CASES[case]
        tmp = path.with_suffix(".part.h5")
        t = time.perf_counter()
        render.synthesize(
            c["preset"],
            tmp,
            duration_s=c["duration_s"],
            seed=seed,
            camera_name=c["camera"],
            line_shape=c.get("render_line_shape"),
        )
        os.replace(tmp, path)
        print(f"  rendered {path.name} in {time.perf_counter() - t:.0f} s", flush=True)
    return path


def surfaces_for(rec, case: str):
    """Surfaces on the truth planes up to 12 cm, and the exit pixel; for the
    crosswind stack, vertical lines 50-150 px downwind of the exit (from the
    preset's geometry), 90 px tall."""
    if case in WIND_DISTANCES_PX:
        from qogi import synth

        name = CASES[case]["preset"]
        view, rel = synth.preset_view(name), synth.preset_release(name)
        fp = view.distance_m * view.ifov_rad
        ex = 0.5 * (view.width_px - 1) + (rel.exit_x_m - view.center_x_m) / fp
        ey = 0.5 * (view.height_px - 1) - (rel.stack_height_m - view.center_z_m) / fp
        side = 1.0 if np.cos(np.radians(rel.wind_direction_deg)) >= 0 else -1.0  # downwind
        return [
            Surface([(ex + side * d, ey - 45), (ex + side * d, ey + 45)], name=f"{d} px")
            for d in WIND_DISTANCES_PX[case]
        ], (ex, ey)
    return truth_surfaces(
        rec, max_height_m=MAX_HEIGHT_M, half_width_px=50 if rec.height == 256 else 40
    )


def result_path(cache: Path, case: str, seed: int, no_source: bool = False) -> Path:
    tag = ".nosource" if no_source else ""
    return cache / f"{case}-{CASES[case]['duration_s']:g}s-seed{seed}{tag}.result.json"


def placed_without_source(rec, surfaces, source):
    """What ``qogi quantify --auto-surfaces`` does without ``--source``: the
    plume and its source detected (:func:`plume_image`, :func:`auto_surfaces`),
    surfaces placed at the case's distances from the true source (each
    surface's midpoint's), and the detected source given to the run.
    Returns ``(surfaces, detected source, placement warnings)``."""
    dists = [
        float(np.hypot(*(np.asarray(s.points, float).mean(axis=0) - np.asarray(source))))
        for s in surfaces
    ]
    placed = Diagnostics()
    auto, detected = auto_surfaces(
        plume_image(rec), dists, source=None, return_source=True, warnings=placed
    )
    return auto, detected, placed


def run_case(cache: Path, case: str, seed: int, no_source: bool = False) -> dict:
    out_json = result_path(cache, case, seed, no_source)
    if out_json.exists():
        return json.loads(out_json.read_text())
    c = CASES[case]
    rec = qogi.open_recording(ensure_recording(cache, case, seed))
    surfaces, source = surfaces_for(rec, case)
    placed = []
    true_source = source
    if no_source:
        try:
            surfaces, source, placed = placed_without_source(rec, surfaces, source)
        except ValueError as e:
            # What `qogi quantify --auto-surfaces` refuses (exit 2): recorded,
            # not quantified.
            d = dict(case=case, seed=seed, placement_error=str(e), surfaces=[], warnings=[])
            out_json.write_text(json.dumps(d, indent=1))
            return d
    cfg = QuantifyConfig(
        species=list(rec.scene.species),
        gas_temperature=c["gas_temperature"],
        composition=c["composition"],
        source=source,
        exit_temperature_K=c.get("exit_temperature_K"),
    )
    t = time.perf_counter()
    res = quantify(rec, surfaces, cfg)
    seconds = time.perf_counter() - t
    if placed:
        res.warnings.extend_unique(placed)
    rows = []
    for s in res.surfaces:
        r = s.species["CH4"]
        rows.append(
            dict(
                surface=s.surface.name,
                mean_kg_h=r.mean_kg_h,
                ci90_kg_h=list(r.ci90_kg_h),
                truth_kg_h=r.truth_kg_h,
                error=r.error_vs_truth,
                covered=bool(r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1]),
                dominant=r.dominant_uncertainty,
                terms=r.uncertainty_terms_kg_h,
                detection_limit_kg_h=r.detection_limit_kg_h,
                error_model=r.error_model,
            )
        )
    info = {k: v for k, v in res.info.items() if isinstance(v, (int, float))}
    for k in ("record_length", "gas_temperature_check", "self_checks"):
        if k in res.info:
            info[k] = res.info[k]
    if res.info.get("background_choice"):
        info["background"] = res.info["background_choice"]["method"]
    d = dict(
        case=case,
        seed=seed,
        seconds=seconds,
        frames=rec.n_frames,
        surfaces=rows,
        info=info,
        warnings=[w.to_dict() for w in res.warnings],
        source=list(source),
        true_source=list(true_source),
        given_source=not no_source,
    )
    out_json.write_text(json.dumps(d, indent=1))
    return d


def report(cache: Path, cases, seeds: int, img_dir: Path | None, no_source: bool = False) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for case in cases:
        dur = f"{CASES[case]['duration_s']:g}s"
        tag = ".nosource" if no_source else ""
        runs = [
            json.loads(p.read_text())
            for p in sorted(cache.glob(f"{case}-{dur}-seed*{tag}.result.json"))
            if no_source or ".nosource." not in p.name
        ]
        refused = [r for r in runs if r["seed"] < seeds and "placement_error" in r]
        for r in refused:
            print(f"{case} seed {r['seed']}: surfaces not placed: {r['placement_error']}")
        runs = [r for r in runs if r["seed"] < seeds and "placement_error" not in r]
        if not runs:
            continue
        names = [s["surface"] for s in runs[0]["surfaces"]]
        print(
            f"\n{case}: {len(runs)} seeds, {CASES[case]['preset']}"
            f"{' via ' + CASES[case]['camera'] if CASES[case]['camera'] else ''}, "
            f"gas temperature {CASES[case]['gas_temperature']}"
            f"{', source detected (not given)' if no_source else ''}"
        )
        print(
            "| surface | mean error | seeds' range | 90 % interval covers truth | dominant term |"
        )
        print("|---|---|---|---|---|")
        errs_all = []
        for i, name in enumerate(names):
            e = np.array([r["surfaces"][i]["error"] for r in runs if len(r["surfaces"]) > i])
            cov = sum(r["surfaces"][i]["covered"] for r in runs if len(r["surfaces"]) > i)
            dom = max(
                {r["surfaces"][i]["dominant"] for r in runs},
                key=[r["surfaces"][i]["dominant"] for r in runs].count,
            )
            errs_all.append(e)
            print(
                f"| {name} | {100 * e.mean():+.1f} % | "
                f"{100 * e.min():+.1f} .. {100 * e.max():+.1f} % | {cov}/{len(e)} | {dom} |"
            )
        big = [(r, s) for r in runs for s in r["surfaces"] if abs(s["error"]) > 0.25]
        flagged = sum(
            any(w.get("surface") == s["surface"] for w in r.get("warnings", [])) for r, s in big
        )
        n_surf = sum(len(r["surfaces"]) for r in runs)
        n_cov = sum(s["covered"] for r in runs for s in r["surfaces"])
        print(
            f"intervals covering: {n_cov}/{n_surf}; surfaces off by more than 25 %: "
            f"{len(big)}, of which {flagged} carry a warning of their own"
        )
        codes: dict = {}
        for r in runs:
            for code in sorted({w["code"] for w in r.get("warnings", [])}):
                codes[code] = codes.get(code, 0) + 1
        if codes:
            print(
                "warnings (seeds): " + ", ".join(f"{k} {v}/{len(runs)}" for k, v in codes.items())
            )
        ls = [
            s["terms"].get("line shape", 0.0) / s["mean_kg_h"]
            for r in runs
            for s in r["surfaces"]
            if s["mean_kg_h"]
        ]
        if ls:
            print(
                f"line-shape term: {100 * np.median(ls):.1f} % of the rate (median; "
                f"{100 * min(ls):.1f} .. {100 * max(ls):.1f} %)"
            )
        secs = np.mean([r["seconds"] for r in runs])
        print(f"quantify: {secs:.0f} s per run of {runs[0]['frames']} frames (mean)")
        if img_dir is not None:
            fig, ax = plt.subplots(figsize=(6, 3.2))
            for i in range(len(names)):
                for r in runs:
                    s = r["surfaces"][i]
                    lo, hi = s["ci90_kg_h"]
                    t = s["truth_kg_h"]
                    x = i + 0.06 * (r["seed"] - seeds / 2)
                    ax.errorbar(
                        x,
                        s["mean_kg_h"] / t,
                        yerr=[[(s["mean_kg_h"] - lo) / t], [(hi - s["mean_kg_h"]) / t]],
                        fmt="o",
                        ms=3,
                        color="C0" if s["covered"] else "C3",
                        lw=0.8,
                    )
            ax.axhline(1.0, color="k", lw=1)
            ax.set_xticks(range(len(names)), names)
            ax.set_ylabel("estimate / truth (90 % interval)")
            ax.set_title(f"{case}: {len(runs)} seeds (red: interval misses truth)")
            fig.tight_layout()
            fig.savefig(img_dir / f"validation-{case}{tag}.png", dpi=90)
            plt.close(fig)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument(
        "--cache",
        type=Path,
        default=Path(
            os.environ.get("QOGI_VALIDATION_CACHE", Path.home() / ".cache" / "qogi" / "validation")
        ),
    )
    ap.add_argument("--render-only", action="store_true", help="only render the recordings")
    ap.add_argument("--report", action="store_true", help="tables and plots from the cache")
    ap.add_argument("--images", type=Path, default=None, help="write plots into this folder")
    ap.add_argument("--redo", action="store_true", help="re-quantify (keep the recordings)")
    ap.add_argument(
        "--no-source",
        action="store_true",
        help="leave the source out, as `qogi quantify --auto-surfaces` does: the "
        "plume's source detected and surfaces placed at the cases' distances from it",
    )
    a = ap.parse_args(argv)
    a.cache.mkdir(parents=True, exist_ok=True)
    if a.report:
        report(a.cache, a.cases, a.seeds, a.images, a.no_source)
        return 0
    for seed in range(a.seeds):
        for case in a.cases:
            if a.render_only:
                ensure_recording(a.cache, case, seed)
                continue
            if a.redo:
                p = result_path(a.cache, case, seed, a.no_source)
                if p.exists():
                    p.unlink()
            d = run_case(a.cache, case, seed, a.no_source)
            print(
                f"{case} seed {seed}: "
                + (
                    f"surfaces not placed: {d['placement_error']}"
                    if "placement_error" in d
                    else ", ".join(
                        f"{s['surface']} {100 * s['error']:+.1f} %"
                        f"{'' if s['covered'] else ' (miss)'}"
                        for s in d["surfaces"]
                    )
                ),
                flush=True,
            )
    report(a.cache, a.cases, a.seeds, a.images, a.no_source)
    return 0


if __name__ == "__main__":
    sys.exit(main())
