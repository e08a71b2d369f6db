"""Weak plumes: the GF320 lab release at 0.5-200 g/h, quantified with the
defaults, against its exact truth (issue 28; docs/validation.md, "Weak
plumes").

The preset ``lab-ch4-5slpm-gf320`` (1.5 m, 12 C plate, gas at ambient) with
only its release rate changed, rendered for ``--duration`` seconds per seed
(cached under ``--cache``), quantified through the truth planes at 6, 8 and
10 cm above the exit with the exit given as the source and every other
setting at its default. Per rate, surface and seed: the error of the mean
rate, whether the 90 % interval covers the truth, the stated detection
limit, whether the rate was "detected", and the run's warnings. The table
(markdown) is printed and, with ``--out``, written to a file.

Usage::

    .venv/bin/python scripts/weak_plume_sweep.py --seeds 4 5 6 --out sweep.md
    .venv/bin/python scripts/weak_plume_sweep.py --rates 2 20 --seeds 0 1 --terms

``--terms`` renders with truth maps and splits each rate into its column
and velocity parts: the flux with the true column at the surface times the
pipeline's normal velocity, and the pipeline's column times the true
mass-weighted velocity (the pipeline's own surface samples, the truth maps
sampled at the same points).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

PRESET = "lab-ch4-5slpm-gf320"
RATES_G_H = (0.5, 2.0, 6.0, 20.0, 60.0, 200.0)
HEIGHTS_M = (0.06, 0.08, 0.10)


def recording_path(cache: Path, rate_g_h: float, seed: int, duration_s: float, maps: bool) -> Path:
    tag = "-maps" if maps else ""
    return cache / f"gf320-{rate_g_h:g}gh-{duration_s:g}s-seed{seed}{tag}.h5"


def ensure_recording(
    cache: Path, rate_g_h: float, seed: int, duration_s: float, maps: bool, progress=None
) -> Path:
    """The preset at ``rate_g_h`` rendered once per seed (truth maps with ``maps``)."""
    from qogi import synth
    from qogi.synth import render

    path = recording_path(cache, rate_g_h, seed, duration_s, maps)
    if path.exists():
        return path
    with_maps = recording_path(cache, rate_g_h, seed, duration_s, True)
    if with_maps.exists():  # the same frames, with truth maps besides
        return with_maps
    p = synth.preset(PRESET)
    release = synth.preset_release(PRESET).replace(rate=float(rate_g_h), rate_unit="g/h")
    sim = synth.simulate(
        release,
        synth.preset_view(PRESET),
        duration_s,
        p["camera"]["frame_rate_hz"],
        seed=seed,
    )
    key, camera = render._camera_for(p)
    bgd = p["scene"]["background"]
    tmp = path.with_suffix(".part.h5")
    render.render_recording(
        sim,
        camera,
        render.Background("plate", bgd["temperature_K"]),
        tmp,
        seed=seed,
        camera_preset_name=key,
        truth_maps=maps,
        progress=progress,
    )
    os.replace(tmp, path)
    return path


def _surface_terms(captured, rec, surfaces_out) -> list:
    """Per surface: mean rate [kg/h] with true columns x the pipeline's normal
    velocity, and with the pipeline's columns x the true velocity, and the
    true columns x true velocity at the same samples (the sampling check)."""
    from qogi.pipeline.sampling import _bilinear

    sp = "CH4"
    cols = rec.truth.datasets[f"column_density_kg_m2_{sp}"]
    vel = rec.truth.datasets["velocity_m_s"]
    out = []
    for j, (xy, n, dl) in enumerate(surfaces_out):
        c_est = np.concatenate([b[j]["c"] for b in captured])
        v_est = np.concatenate([b[j]["v"] for b in captured])
        nt = len(c_est)
        c_true = np.empty_like(c_est)
        v_true = np.empty_like(c_est)
        for f in range(nt):
            c_true[f] = _bilinear(np.asarray(cols[f], float)[None], xy)[0]
            ux = _bilinear(np.nan_to_num(np.asarray(vel[f, 0], float))[None], xy)[0]
            uz = _bilinear(np.nan_to_num(np.asarray(vel[f, 1], float))[None], xy)[0]
            # image normal (x right, y down); velocity maps: x right, z up
            v_true[f] = ux * n[:, 0] - uz * n[:, 1]
        c0 = np.where(np.isfinite(c_est), c_est, 0.0)
        k = 3600.0
        out.append(
            dict(
                est=float(np.mean((c0 * v_est) @ dl)) * k,
                true_c_est_v=float(np.mean((c_true * v_est) @ dl)) * k,
                est_c_true_v=float(np.mean((c0 * v_true) @ dl)) * k,
                true_c_true_v=float(np.mean((c_true * v_true) @ dl)) * k,
                sum_c_est=float(np.mean(c0 @ dl)),
                sum_c_true=float(np.mean(c_true @ dl)),
            )
        )
    return out


def run(cache: Path, rate_g_h: float, seed: int, duration_s: float, terms: bool, bar) -> dict:
    import qogi
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.pipeline.surfaces import truth_surfaces

    out_json = recording_path(cache, rate_g_h, seed, duration_s, terms).with_suffix(".result.json")
    if out_json.exists():
        return json.loads(out_json.read_text())
    path = ensure_recording(
        cache, rate_g_h, seed, duration_s, terms, progress=lambda f, m: bar(0.6 * f, m)
    )
    rec = qogi.open_recording(path)
    surfaces, source = truth_surfaces(rec, heights_m=HEIGHTS_M, half_width_px=40)
    cfg = QuantifyConfig(species=["CH4"], source=source)
    captured: list = []
    restore = None
    if terms:
        from qogi.pipeline import flux as flux_stage

        restore = flux_stage._surface_flux

        def spy(c, sig, vn, dl, speed_floor=0.0):
            if not captured or len(captured[-1]) == len(surfaces):
                captured.append([])
            captured[-1].append(dict(c=np.array(c), v=np.array(vn)))
            return restore(c, sig, vn, dl, speed_floor)

        flux_stage._surface_flux = spy
    try:
        t = time.perf_counter()
        res = quantify(rec, surfaces, cfg, progress=lambda f, m: bar(0.6 + 0.4 * f, m))
        seconds = time.perf_counter() - t
    finally:
        if restore is not None:
            flux_stage._surface_flux = restore
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
                limit_kg_h=r.detection_limit_kg_h,
                detected=r.detected,
                text=r.text("g/h"),
            )
        )
    d = dict(
        rate_g_h=rate_g_h,
        seed=seed,
        seconds=seconds,
        surfaces=rows,
        warnings=sorted({w.code for w in res.warnings}),
    )
    if terms:
        pixel_m = rec.scene.distance_m * rec.camera.ifov_rad
        samples = []
        for s in surfaces:
            xy, n, dl = s.oriented_away_from(source).samples(step_px=1.0)
            samples.append((xy, n, dl * pixel_m))
        d["terms"] = _surface_terms(captured, rec, samples)
    out_json.write_text(json.dumps(d, indent=1))
    return d


def table(runs: list, terms: bool) -> str:
    """The markdown table: one row per rate, the surfaces side by side."""
    lines = [
        "| release | seeds | mean error (6 / 8 / 10 cm) | seeds' range | interval covers "
        "| detected | stated limit | warnings |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for rate in sorted({r["rate_g_h"] for r in runs}):
        rr = [r for r in runs if r["rate_g_h"] == rate]
        ns = len(rr[0]["surfaces"])
        errs = np.array([[r["surfaces"][i]["error"] for i in range(ns)] for r in rr])
        cov = sum(s["covered"] for r in rr for s in r["surfaces"])
        det = sum(bool(s["detected"]) for r in rr for s in r["surfaces"])
        lim = [s["limit_kg_h"] * 1e3 for r in rr for s in r["surfaces"] if s["limit_kg_h"]]
        warn: dict = {}
        for r in rr:
            for w in r["warnings"]:
                warn[w] = warn.get(w, 0) + 1
        lines.append(
            f"| {rate:g} g/h | {','.join(str(r['seed']) for r in rr)} | "
            + " / ".join(f"{100 * e:+.0f} %" for e in errs.mean(axis=0))
            + f" | {100 * errs.min():+.0f} .. {100 * errs.max():+.0f} % | {cov}/{errs.size} | "
            f"{det}/{errs.size} | "
            + (f"{min(lim):.2g}-{max(lim):.2g} g/h" if lim else "none")
            + " | "
            + (", ".join(f"{k} {v}/{len(rr)}" for k, v in sorted(warn.items())) or "-")
            + " |"
        )
    if terms:
        lines += [
            "",
            "Rate parts (mean over seeds, as a fraction of the truth; 6 / 8 / 10 cm):",
            "",
            "| release | pipeline | true c x its v | its c x true v | true c x true v "
            "| its sum c / true |",
            "|---|---|---|---|---|---|",
        ]
        for rate in sorted({r["rate_g_h"] for r in runs if "terms" in r}):
            rr = [r for r in runs if r["rate_g_h"] == rate and "terms" in r]
            truth = rr[0]["surfaces"][0]["truth_kg_h"]

            def part(key, rr=rr, truth=truth):
                n = len(rr[0]["terms"])
                return " / ".join(
                    f"{np.mean([r['terms'][i][key] for r in rr]) / truth:.2f}" for i in range(n)
                )

            n = len(rr[0]["terms"])
            ratio = " / ".join(
                "{:.2f}".format(
                    np.mean([r["terms"][i]["sum_c_est"] / r["terms"][i]["sum_c_true"] for r in rr])
                )
                for i in range(n)
            )
            lines.append(
                f"| {rate:g} g/h | {part('est')} | {part('true_c_est_v')} | "
                f"{part('est_c_true_v')} | {part('true_c_true_v')} | {ratio} |"
            )
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=list(RATES_G_H), help="g/h")
    ap.add_argument("--seeds", type=int, nargs="+", default=[4, 5, 6])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds rendered per run")
    ap.add_argument(
        "--cache",
        type=Path,
        default=Path(
            os.environ.get("QOGI_SWEEP_CACHE", Path.home() / ".cache" / "qogi" / "weak-plumes")
        ),
    )
    ap.add_argument("--terms", action="store_true", help="split the rate into its parts")
    ap.add_argument("--redo", action="store_true", help="re-quantify (keep the recordings)")
    ap.add_argument("--render-only", action="store_true", help="only render the recordings")
    ap.add_argument("--out", type=Path, help="write the markdown table here")
    a = ap.parse_args(argv)
    from qogi._progress import ProgressBar

    a.cache.mkdir(parents=True, exist_ok=True)
    jobs = [(r, s) for r in a.rates for s in a.seeds]
    runs = []
    bar = ProgressBar("sweep ")
    try:
        for k, (rate, seed) in enumerate(jobs):
            res_path = recording_path(a.cache, rate, seed, a.duration, a.terms).with_suffix(
                ".result.json"
            )
            if a.redo and res_path.exists():
                res_path.unlink()

            def say(f, m, k=k, rate=rate, seed=seed):
                return bar((k + f) / len(jobs), f"{rate:g} g/h seed {seed}: {m}")

            if a.render_only:
                ensure_recording(a.cache, rate, seed, a.duration, a.terms, progress=say)
                continue

            runs.append(run(a.cache, rate, seed, a.duration, a.terms, say))
        bar(1.0, "done")
    finally:
        bar.close()
    if a.render_only:
        return 0
    text = table(runs, a.terms)
    print(text)
    if a.out:
        a.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
