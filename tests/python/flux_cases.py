"""Seeded synthetic inputs for the flux engine's comparison test
(tests/python/test_flux_engine.py) and the frozen outputs of the numpy
implementation it replaced (tests/data/flux_reference.npz, written once by
scripts/freeze_flux_reference.py at commit 6f8e8db, before the port)."""

from __future__ import annotations

import numpy as np

from qogi.measure import velocimetry as vel


def puffing_plume(
    seed: int, frames: int = 40, height: int = 64, width: int = 48, speed_px: float = 2.3
) -> np.ndarray:
    """(T, H, W) float32 column field of a plume rising from the bottom edge
    at ``speed_px`` px/frame with puffs of random strength and a random
    cross-profile wobble (not an exact transport: a comparison input)."""
    rng = np.random.default_rng(seed)
    y = np.arange(height, dtype=float)
    x = np.arange(width, dtype=float)
    phases = rng.uniform(0, 2 * np.pi, 4)
    periods = rng.uniform(6.0, 25.0, 4)
    out = np.empty((frames, height, width), np.float32)
    for t in range(frames):
        s = t - (height - 1 - y) / speed_px  # release time of each row
        q = 1.0 + sum(0.25 * np.sin(2 * np.pi * s / p + ph) for p, ph in zip(periods, phases))
        sig = 3.0 + 0.08 * (height - 1 - y)
        xc = 0.5 * width + 1.5 * np.sin(0.3 * s)
        g = np.exp(-0.5 * ((x[None, :] - xc[:, None]) / sig[:, None]) ** 2) / sig[:, None]
        out[t] = (q[:, None] * g * (1.0 + 0.02 * rng.standard_normal((height, width)))).astype(
            np.float32
        )
    return np.clip(out, 0.0, None)


def frame_velocities(seed: int, shape: tuple, axis: str, level: float) -> tuple:
    """Smooth, noisy (u, v) [px/frame] at the frames' times moving along
    ``axis`` at about ``level`` px/frame."""
    rng = np.random.default_rng(seed + 100)
    T, H, W = shape
    y = np.linspace(0, 1, H)[None, :, None]
    x = np.linspace(0, 1, W)[None, None, :]
    base = (
        level * (1.0 + 0.2 * np.sin(3 * y + 2 * x)) * (1.0 + 0.05 * rng.standard_normal((T, 1, 1)))
    )
    along = base + 0.1 * rng.standard_normal((T, H, W))
    across = 0.2 * rng.standard_normal((T, H, W))
    sign = -1.0 if axis in ("up", "left") else 1.0
    if axis in ("up", "down"):
        return across.astype(np.float32), (sign * along).astype(np.float32)
    return (sign * along).astype(np.float32), across.astype(np.float32)


def turned(stack: np.ndarray, axis: str) -> np.ndarray:
    """The upward plume ``stack`` turned so that it moves along ``axis``."""
    if axis == "up":
        return np.ascontiguousarray(stack)
    if axis == "down":
        return np.ascontiguousarray(stack[:, ::-1, :])
    if axis == "left":
        return np.ascontiguousarray(stack.transpose(0, 2, 1))
    return np.ascontiguousarray(stack[:, ::-1, :].transpose(0, 2, 1))


#: (name, seed, axis, source_index in the turned frame or None, intervals kind)
TRANSPORT_CASES = [
    ("up", 1, "up", None, None),
    ("up_source", 2, "up", 58.0, None),
    ("down", 3, "down", 6.0, None),
    ("left", 4, "left", None, None),
    ("right_dropped", 5, "right", 5.0, "dropped"),
]


def intervals(kind, frames: int, seed: int):
    if kind is None:
        return None
    r = np.ones(frames - 1)
    r[np.random.default_rng(seed).choice(frames - 1, 5, replace=False)] = 2.0
    return r


def surface_case(seed: int, frames: int = 30, samples: int = 25) -> tuple:
    """(c, sig, vn, dl): columns [kg/m2] with NaN samples (and one frame all
    NaN), their sigma, normal velocities [m/s] and segment lengths [m]."""
    rng = np.random.default_rng(seed)
    y = np.linspace(-1, 1, samples)
    c = np.exp(-0.5 * (y / 0.4) ** 2)[None, :] * rng.uniform(0.5, 1.5, (frames, 1)) * 1e-4
    c = c + 1e-6 * rng.standard_normal((frames, samples))
    c[rng.random((frames, samples)) < 0.1] = np.nan
    c[3] = np.nan
    sig = np.abs(1e-6 * rng.standard_normal((frames, samples)))
    vn = 0.8 + 0.3 * rng.standard_normal((frames, samples))
    vn[rng.random((frames, samples)) < 0.05] *= -1
    dl = np.full(samples, 2.0 / (samples - 1)) * rng.uniform(0.9, 1.1, samples)
    return c, sig, vn, dl


def digest(a: np.ndarray) -> np.ndarray:
    """A (T, H, W) velocity stack's sums per frame, per row and per column
    and its last frame's middle row (float64): enough to compare two stacks
    whose lines are scaled by factors, without storing them."""
    a = np.asarray(a, np.float64)
    return np.concatenate(
        [a.sum(axis=(1, 2)), a.sum(axis=(0, 2)), a.sum(axis=(0, 1)), a[-1, a.shape[1] // 2]]
    )


def flow_sequence_case() -> tuple:
    """The flux level's sequence input: the puffing plume of seed 7, its frame
    velocities (fu, fv) upwards at level 1.8, and those from frame 1 on as an
    exact FlowSequence (quality 1, every vector valid, residual 0)."""
    frames = puffing_plume(7)
    fu, fv = frame_velocities(7, frames.shape, "up", 1.8)
    seq = vel.FlowSequence(
        fu[1:],
        fv[1:],
        np.ones_like(fu[1:]),
        np.ones(fu[1:].shape, bool),
        np.zeros(fu.shape[0] - 1),
        "exact",
    )
    return frames, fu, fv, seq


def calibrate_given_transport(frames, fu, fv) -> tuple:
    """The flux level (u, v, scale) of the sequence case's rows 20 on, given
    the transport of the whole plume's rows 20-63 scaled by 1.3."""
    part = vel.transport_flux(frames, "up").lines(slice(20, 64), scale=1.3)
    return vel.calibrate_flux_level(
        None,
        frames[:, 20:],
        "up",
        transport=part,
        frame_velocities=(fu[:, 20:].copy(), fv[:, 20:].copy()),
    )
