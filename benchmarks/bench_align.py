"""Per-frame cost of the alignment stage (qogi.pipeline.align) on 320 x 256 frames.

A textured scene shaken by 0.5 px rms (exactly rendered plane waves) is
registered frame by frame to its reference and resampled back; a four-channel
frame is brought to its turn's time (optical flow between the neighbouring
turns, each channel moved along it). Each figure is printed against baselines
timed in the same run:

* ``frame copy``: copying the frame (the memory-bound floor);
* ``cv2 DIS medium``: one OpenCV-Python dense-inverse-search flow on the frame
  pair (what the velocity stage spends per frame at least);
* ``cv2 findTransformECC``: OpenCV's Euclidean ECC registration of the frame,
  the off-the-shelf alternative to the engine's robust registration.

Timings are the best of three runs over the frames (the machine is shared);
the load average is printed before and after. No time is asserted anywhere.

Usage: python benchmarks/bench_align.py [--frames N]
"""

from __future__ import annotations

import argparse
import os
import time

import cv2
import numpy as np

from qogi import _engine
from qogi.synth.render import Jitter

H, W = 256, 320


def scene(n: int):
    rng = np.random.default_rng(3)
    k = 2 * np.pi / rng.uniform(5, 30, 40)
    d = rng.uniform(0, 2 * np.pi, 40)
    ph = rng.uniform(0, 2 * np.pi, 40)
    y, x = np.mgrid[0:H, 0:W].astype(float)
    motion = Jitter(rms_px=0.5, seed=1).motion(np.arange(n) / 30.0)
    frames = []
    for dx, dy, _a in motion:
        xs, ys = x - dx, y - dy
        img = np.cos(k * np.cos(d) * xs[..., None] + k * np.sin(d) * ys[..., None] + ph).sum(-1)
        frames.append(img + rng.normal(0, 0.1, img.shape))
    return np.asarray(frames, np.float32), motion


def best_of(fn, frames, repeats=3) -> float:
    best = np.inf
    for _ in range(repeats):
        t0 = time.perf_counter()
        for f in frames:
            fn(f)
        best = min(best, (time.perf_counter() - t0) / len(frames))
    return best


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=20)
    args = ap.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    frames, motion = scene(args.frames)
    ref = np.median(frames, axis=0).astype(np.float32)
    reg = _engine.FrameRegistration(ref)
    u8 = [cv2.normalize(f, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8) for f in frames]
    dis = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_MEDIUM)
    u = np.full((H, W), 0.5, np.float32)
    four = np.repeat(frames[:, None], 4, axis=1)

    def stabilise(f):
        r = reg.register(f)
        _engine.warp_to_reference(f, r["dx_px"], r["dy_px"], r["angle_rad"])

    def ecc(f):
        warp = np.eye(2, 3, dtype=np.float32)
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 1e-3)
        cv2.findTransformECC(ref, f, warp, cv2.MOTION_EUCLIDEAN, crit, None, 1)

    pairs = list(zip(u8[:-1], u8[1:]))
    timings = {
        "frame copy": best_of(lambda f: f.copy(), frames),
        "cv2 DIS medium (one pair)": best_of(lambda p: dis.calc(p[0], p[1], None), pairs),
        "cv2 findTransformECC (Euclidean)": best_of(ecc, frames),
        "register + resample (one channel)": best_of(stabilise, frames),
        "resample along a flow, 4 channels": best_of(
            lambda f: _engine.warp_along_flow(f, u, u, 0.25), four
        ),
    }
    base = timings["cv2 DIS medium (one pair)"]
    for name, t in timings.items():
        print(f"{name:>36}: {t * 1e3:8.3f} ms/frame  ({t / base:6.2f} x DIS medium)")
    est = np.array([[reg.register(f)[k] for k in ("dx_px", "dy_px")] for f in frames])
    err = est - motion[:, :2]
    err -= err.mean(axis=0)
    print(
        f"registration error (rms, about the reference's place): {np.sqrt(np.mean(err**2)):.4f} px"
    )
    print(f"load average after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
