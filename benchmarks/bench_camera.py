"""Speed of the camera module: calibration, NETD noise, warm optics.

Each figure is printed with a baseline timed in the same run:
- Calibration.counts_to_radiance of a 50 x 4 x 256 x 320 raw stack vs the
  same per-pixel arithmetic ((a raw / t + b - O) / G) written in numpy
  (which has no bad-pixel or range handling);
- fit_calibration from 5 scenes x 20 frames x 4 channels vs numpy's mean
  over the same frames (the one pass any fit must make);
- add_netd_noise on a 50 x 4 x 256 x 320 stack vs numpy's PCG64
  standard_normal(float32) times sigma on the same shape;
- ChannelOptics.warm_radiance (3 band integrals) vs one band_radiance of
  the same channel.

Run: .venv/bin/python benchmarks/bench_camera.py
"""

from __future__ import annotations

import numpy as np
from _timing import best_time

from qogi import _engine
from qogi.physics.camera import CalibrationScene, add_netd_noise, camera_optics, fit_calibration


def main():
    optics = camera_optics("fast-m150")
    chans = [o.response for o in optics]
    nc, h, w = 4, 256, 320
    rng = np.random.default_rng(1)
    l360 = np.array([ch.band_radiance(360.0) for ch in chans])
    g = (3.0e7 / l360)[:, None, None] * (1 + 0.05 * rng.standard_normal((nc, h, w)))
    o = 3.0e6 * (1 + 0.1 * rng.standard_normal((nc, h, w)))

    def frames(t_k, n):
        lum = np.array([ch.band_radiance(t_k) for ch in chans])[:, None, None]
        c = 1e-3 * (g * lum + o)
        return (c + 2.0 * rng.standard_normal((n, nc, h, w))).astype(np.float32)

    scenes = [CalibrationScene(t, frames(t, 20), 1e-3) for t in (283.0, 303.0, 323.0, 343.0, 363.0)]
    t_fit = best_time(lambda: fit_calibration(scenes, chans), 1)
    t_mean = best_time(lambda: [s.frames.mean(axis=0) for s in scenes], 1)
    print(
        f"fit_calibration, 5 scenes x 20 frames x 4 x 256 x 320: {t_fit * 1e3:.0f} ms; "
        f"numpy mean over the same frames: {t_mean * 1e3:.0f} ms; ratio {t_fit / t_mean:.2f}"
    )

    cal = fit_calibration(scenes, chans)
    raw = frames(300.0, 50)
    t_cal = best_time(lambda: cal.counts_to_radiance(raw, 1e-3))
    a = np.stack([c.nuc_gain for c in cal.channels]).astype(np.float32)
    b = np.stack([c.nuc_offset for c in cal.channels]).astype(np.float32)
    big_g = np.array([c.curve.gain for c in cal.channels], np.float32)[:, None, None]
    big_o = np.array([c.curve.offset for c in cal.channels], np.float32)[:, None, None]
    t_np = best_time(lambda: (a * raw / np.float32(1e-3) + b - big_o) / big_g)
    print(
        f"counts_to_radiance, 50 x 4 x 256 x 320 float32: {t_cal * 1e3:.0f} ms; "
        f"numpy arithmetic: {t_np * 1e3:.0f} ms; ratio {t_cal / t_np:.2f}"
    )

    lum = np.full((50, nc, h, w), 0.2, np.float32)
    t_noise = best_time(lambda: add_netd_noise(lum, chans, 0.017, 288.15, seed=1))
    sigma = np.float32(1e-4)
    gen = np.random.default_rng(2)
    t_pcg = best_time(lambda: lum + sigma * gen.standard_normal(lum.shape, dtype=np.float32))
    print(
        f"add_netd_noise, 50 x 4 x 256 x 320: {t_noise * 1e3:.0f} ms "
        f"({_engine.resolve_threads(0)} threads); numpy PCG64 normal + add: "
        f"{t_pcg * 1e3:.0f} ms; ratio {t_noise / t_pcg:.2f}"
    )

    co2 = optics[1]
    r = co2.response
    t_w = best_time(lambda: co2.warm_radiance(293.15, 293.15), 20)
    t_l = best_time(lambda: r.band_radiance(293.15), 20)
    print(
        f"warm_radiance (CO2 channel): {t_w * 1e6:.0f} us; one band_radiance: "
        f"{t_l * 1e6:.0f} us; ratio {t_w / t_l:.2f}"
    )


if __name__ == "__main__":
    main()
