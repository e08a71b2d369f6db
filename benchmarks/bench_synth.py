"""Speed of the synthetic-plume simulator and its exact truth.

Scene: the `lab-ch4co2-90c-m150` preset, 700 frames at 100 Hz of a 320x256
view (the thesis's four-channel release). Timed in this run:

* simulation (puff dynamics, including spin-up),
* truth maps (column density and mass-weighted velocity) of all 700 frames,
* the ray samples a renderer consumes (mole fractions and temperature along
  every pixel's line of sight), on a subset of frames, extrapolated to 700.

Baseline, timed in the same run: a plain numpy evaluation of the same column
map (each puff's separable Gaussian added over its 7-width patch), on a few
frames, extrapolated to 700. Rendering (radiative transfer through the camera
channels) is not part of this module and is left out of the projected total.
"""

from __future__ import annotations

import os
import time

import numpy as np

from qogi import synth

PRESET = "lab-ch4co2-90c-m150"
RAY_FRAMES = 20
BASELINE_FRAMES = 5
BUDGET_S = 600.0  # issue target: 700 frames simulated and rendered in 10 min


def numpy_column_map(puffs: np.ndarray, view) -> np.ndarray:
    """Column density of one frame by plain numpy (orthographic)."""
    h, w = view.height_px, view.width_px
    fp = view.footprint_m
    xs = view.center_x_m + (np.arange(w) - 0.5 * (w - 1)) * fp
    zs = view.center_z_m - (np.arange(h) - 0.5 * (h - 1)) * fp
    out = np.zeros((h, w))
    for x, _, z, _, _, _, s, _, m in puffs.astype(np.float64):
        i0, i1 = np.searchsorted(xs, [x - 7 * s, x + 7 * s])
        k1, k0 = np.searchsorted(-zs, [-(z - 7 * s), -(z + 7 * s)])
        if i0 >= i1 or k0 >= k1:
            continue
        gx = np.exp(-0.5 * ((xs[i0:i1] - x) / s) ** 2)
        gz = np.exp(-0.5 * ((zs[k0:k1] - z) / s) ** 2)
        out[k0:k1, i0:i1] += m / (2 * np.pi * s * s) * np.outer(gz, gx)
    return out


def main() -> None:
    threads = os.cpu_count() or 1
    p = synth.preset(PRESET)
    n_frames = round(p["duration_s"] * p["camera"]["frame_rate_hz"])

    t0 = time.perf_counter()
    sim = synth.simulate_preset(PRESET)
    t_sim = time.perf_counter() - t0
    assert sim.num_frames == n_frames

    t0 = time.perf_counter()
    for f in range(sim.num_frames):
        sim.truth_maps(f)
    t_maps = time.perf_counter() - t0

    frames = np.linspace(0, sim.num_frames - 1, RAY_FRAMES).astype(int)
    samples = 0
    t0 = time.perf_counter()
    for f in frames:
        for r0 in range(0, sim.view.height_px, 32):
            rs = sim.ray_samples(int(f), rows=(r0, min(r0 + 32, sim.view.height_px)))
            samples += rs["temperature_K"].size
    t_rays = (time.perf_counter() - t0) * sim.num_frames / RAY_FRAMES

    t0 = time.perf_counter()
    for f in frames[:BASELINE_FRAMES]:
        ref = numpy_column_map(sim.puffs(int(f)), sim.view)
    t_base = (time.perf_counter() - t0) * sim.num_frames / BASELINE_FRAMES
    # The baseline computes the same thing (a check, not a timing).
    col = sim.truth_maps(int(frames[BASELINE_FRAMES - 1]))["column_kg_m2"]
    total_col = sum(c.astype(np.float64) for c in col.values())
    assert np.allclose(total_col, ref, rtol=1e-4, atol=1e-6 * ref.max())

    total = t_sim + t_maps + t_rays
    print(
        f"scene: {PRESET}, {sim.num_frames} frames of {sim.view.width_px}x{sim.view.height_px}, "
        f"{sim.stats['max_live_puffs']} puffs at most, {threads} threads"
    )
    print(
        f"baseline (numpy column maps, {BASELINE_FRAMES} frames "
        f"x {sim.num_frames // BASELINE_FRAMES}): {t_base:8.2f} s for {sim.num_frames} frames"
    )
    print(
        f"simulation (incl. {sim.spin_up_s:.1f} s spin-up):      {t_sim:8.2f} s   "
        f"= {t_sim / t_base:.3f} x baseline"
    )
    print(
        f"truth maps, all frames:                 {t_maps:8.2f} s   "
        f"= {t_maps / t_base:.3f} x baseline  ({1e3 * t_maps / sim.num_frames:.1f} ms/frame)"
    )
    print(
        f"ray samples ({RAY_FRAMES} frames x {sim.num_frames // RAY_FRAMES}):"
        f"           {t_rays:8.2f} s   = {t_rays / t_base:.3f} x baseline  "
        f"({samples / RAY_FRAMES / 1e6:.1f} M samples/frame)"
    )
    print(
        f"projected total without rendering:      {total:8.2f} s   "
        f"= {total / t_base:.3f} x baseline  ({100 * total / BUDGET_S:.1f} % of the 10 min budget)"
    )


if __name__ == "__main__":
    main()
