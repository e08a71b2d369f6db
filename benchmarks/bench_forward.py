"""Forward models: evaluations per second of the exact and the fast model for
one 4-channel pixel (fast-m150, CH4 + CO2 with self-broadening, HITRAN tables),
in the same run, and the fast model's worst error over the issue's domain.

Baseline: the exact line-by-line model. Target: fast >= 100x exact."""

import os
import pathlib
import time

import numpy as np

import qogi

HITRAN = (
    pathlib.Path(
        os.environ.get("QOGI_SHARED_DIR", pathlib.Path(__file__).resolve().parents[2] / "shared")
    )
    / "hitran"
)


def rate(fn, min_time=2.0):
    n, t0 = 0, time.perf_counter()
    while True:
        fn()
        n += 1
        dt = time.perf_counter() - t0
        if dt >= min_time and n >= 2:
            return n / dt


def main():
    cam = qogi.camera_preset("fast-m150")
    t0 = time.perf_counter()
    model = qogi.ForwardModel(
        cam, ["CH4", "CO2"], line_lists={"CH4": HITRAN / "CH4.par", "CO2": HITRAN / "CO2.par"}
    )
    fast = model.fast
    print(
        f"tables + fast model ready in {time.perf_counter() - t0:.1f} s; bins per channel "
        f"{[fast.num_bins(c) for c in range(len(cam.channels))]}"
    )
    plume = ({"CH4": 0.05, "CO2": 0.05}, 340.0, 0.03, 293.0, 283.0)
    r_exact = rate(lambda: model.band_radiance(*plume, exact=True), 5.0)
    r_fast = rate(lambda: model.band_radiance(*plume, num_threads=1))
    print(
        f"one 4-channel pixel: exact {r_exact:.3g} eval/s, fast {r_fast:.3g} eval/s "
        f"(1 thread): fast = {r_fast / r_exact:.0f}x exact (target >= 100x)"
    )
    # A batch uses both cores.
    n = 200
    batch = ({"CH4": np.full(n, 0.05), "CO2": np.full(n, 0.05)}, 340.0, 0.03, 293.0, 283.0)
    r_batch = rate(lambda: model.band_radiance(*batch)) * n
    print(f"fast, batch of {n} pixels on all cores: {r_batch:.3g} pixels/s")

    rng = np.random.default_rng(7)
    worst_c = np.zeros(4)
    worst_l = np.zeros(4)
    draws = int(os.environ.get("QOGI_BENCH_DRAWS", "30"))
    for k in range(draws):
        ta = rng.uniform(250, 320)
        tp = ta + rng.uniform(-30, 200)
        which = k % 3
        x1 = 10 ** rng.uniform(-5, 0) if which != 1 else 0.0
        x2 = (1 - x1) * 10 ** rng.uniform(-5, 0) if which != 0 else 0.0
        sg, tb = 10 ** rng.uniform(-3, np.log10(0.5)), rng.uniform(250, 350)
        le = model.band_radiance({"CH4": x1, "CO2": x2}, tp, sg, ta, tb, exact=True)
        lf = model.band_radiance({"CH4": x1, "CO2": x2}, tp, sg, ta, tb)
        bg = model.background_radiance(tb)
        worst_c = np.maximum(worst_c, np.abs(lf - le) / np.maximum(np.abs(le - bg), 1e-4 * bg))
        worst_l = np.maximum(worst_l, np.abs(lf / le - 1))
    print(
        f"fast vs exact over {draws} random plumes (x 0-1 CH4/CO2 alone and mixed, T_amb "
        f"250-320 K, T_peak T_amb-30..+200 K, sigma 1 mm-0.5 m, T_bg 250-350 K):"
    )
    for c, ch in enumerate(cam.channels):
        print(
            f"  {ch.name:24s} worst contrast error {100 * worst_c[c]:.3f} %  "
            f"worst L error {100 * worst_l[c]:.4f} %"
        )


if __name__ == "__main__":
    main()
