"""The flux level's transport on a release's exact columns (issue 28 item 2;
docs/validation.md, "The flux level over a long record").

The GF320 lab preset ``lab-ch4-5slpm-gf320`` with only its release rate
changed is simulated (no rendering) for ``--duration`` seconds per seed; its
truth maps give the exact columns and the exact flux through each row. Per
rate and seed, at the rows 6, 8 and 10 cm above the exit: the transport's
flux (:func:`qogi.measure.velocimetry.transport_flux`) with one fit over the record
and with windows of :data:`qogi.measure.velocimetry.TRANSPORT_WINDOW_S`, as
fractions of the true time-averaged flux, and, with ``--terms``, what the
time average hides: ``mean(c) mean(u) / mean(c u)`` and the correlation of
the line column and the line's mass-weighted speed.

Usage::

    .venv/bin/python scripts/transport_on_truth.py --rates 2 20 --seeds 0 1 2 3 4 5
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

PRESET = "lab-ch4-5slpm-gf320"
HEIGHTS_M = (0.06, 0.08, 0.10)


def truth_lines(rate_g_h: float, seed: int, duration_s: float):
    """Exact columns (T, H, W) [kg/m2], line fluxes (T, H) [kg/s] upwards
    through each row, the rows at HEIGHTS_M, the source row, the pixel [m]
    and the frame rate [Hz]."""
    from qogi import synth

    p = synth.preset(PRESET)
    fps = p["camera"]["frame_rate_hz"]
    release = synth.preset_release(PRESET).replace(rate=float(rate_g_h), rate_unit="g/h")
    view = synth.preset_view(PRESET)
    sim = synth.simulate(release, view, duration_s, fps, seed=seed)
    T = sim.num_frames
    col = np.empty((T, view.height_px, view.width_px), np.float32)
    flux = np.empty((T, view.height_px))
    pixel = view.distance_m * view.ifov_rad
    for t in range(T):
        m = sim.truth_maps(t)
        col[t] = m["column_kg_m2"]["CH4"]
        flux[t] = m["flux_z_kg_m_s"]["CH4"].sum(axis=1) * pixel
    exit_row = p["scene"]["exit_pixel"][1]
    rows = [int(round(exit_row - h / pixel)) for h in HEIGHTS_M]
    return col, flux, rows, exit_row, pixel, fps


def main(argv=None) -> int:
    from qogi.measure import velocimetry as vel

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[2.0, 20.0], help="g/h")
    ap.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3])
    ap.add_argument("--duration", type=float, default=10.0, help="seconds simulated per run")
    ap.add_argument("--terms", action="store_true", help="the covariance terms too")
    a = ap.parse_args(argv)
    print(
        "| release, seed | one fit | windows | "
        + ("mean(c) mean(u) / mean(c u) | corr(c, u) |" if a.terms else "")
    )
    print("|---|---|---|" + ("---|---|" if a.terms else ""))
    ratios: dict = {0: [], 1: []}
    for rate in a.rates:
        for seed in a.seeds:
            col, flux, rows, exit_row, pixel, fps = truth_lines(rate, seed, a.duration)
            window = max(4, int(round(vel.TRANSPORT_WINDOW_S * fps)))
            true = flux[:, rows].mean(axis=0)
            cells = []
            for i, w in enumerate((0, window)):
                tf = vel.transport_flux(col, "up", exit_row, window=w)
                r = tf.flux[rows] * pixel**2 * fps / true
                ratios[i].append(r)
                cells.append(" / ".join(f"{x:.2f}" for x in r))
            line = f"| {rate:g} g/h, {seed} | {cells[0]} | {cells[1]} |"
            if a.terms:
                c = col.sum(axis=2)[:, rows] * pixel  # kg per m of height
                u = flux[:, rows] / c
                cov = c.mean(axis=0) * u.mean(axis=0) / (c * u).mean(axis=0)
                corr = [np.corrcoef(c[:, j], u[:, j])[0, 1] for j in range(len(rows))]
                line += " " + " / ".join(f"{x:.3f}" for x in cov) + " | "
                line += " / ".join(f"{x:+.2f}" for x in corr) + " |"
            print(line, flush=True)
    for i, name in enumerate(("one fit", f"{vel.TRANSPORT_WINDOW_S:g} s windows")):
        x = np.array(ratios[i])
        print(
            f"{name}: mean {x.mean():.3f}, spread over runs {x.mean(axis=1).std():.3f}, "
            f"{x.min():.2f} ... {x.max():.2f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
