"""Turning frames into pictures: channel selection, quantity, colour maps, ranges.

Everything here is numpy on one (H, W) image at a time, written into
preallocated buffers so that playback of a 320x256 recording at 100 Hz costs
a few milliseconds per drawn frame (``benchmarks/bench_gui.py``).

Quantities are the recording contract's: band radiance [W/(m2 sr)] or
radiometric temperature [K], converted per channel through the channel's
spectral response with :func:`qogi.radiometry.band_table` (only the channel
on screen is converted).
"""

from __future__ import annotations

from functools import cache
from typing import Optional, Tuple

import numpy as np

__all__ = [
    "COLORMAPS",
    "QUANTITY_LABELS",
    "colormap_lut",
    "read_channel",
    "robust_range",
    "recording_range",
    "colorize",
    "colorize_overlay",
    "to_uint8_rgb",
]

#: Colour maps offered for the video (matplotlib names); the first is the default.
COLORMAPS = ("inferno", "gray", "magma", "viridis", "plasma", "cividis", "turbo", "hot")
#: What the overlay shows: the shown frame's column density (maps kept by
#: the run), or the run's minimum-detectable column (one map for the run:
#: where in the frame the camera can see the gas at all).
OVERLAY_KINDS = ("column density", "minimum-detectable column")

#: Colour maps offered for the column-density overlay.
OVERLAY_COLORMAPS = ("viridis", "turbo", "plasma", "cool", "winter")
QUANTITY_LABELS = {
    "radiance": "band radiance [W/(m2 sr)]",
    "radiometric_temperature": "radiometric temperature [K]",
}
#: Percentiles of the robust ("auto") display range.
AUTO_PERCENTILES = (0.5, 99.5)


@cache
def colormap_lut(name: str, n: int = 256) -> np.ndarray:
    """(n, 4) float32 RGBA table in [0, 1] of the matplotlib colour map ``name``."""
    import matplotlib

    try:
        cmap = matplotlib.colormaps[name]
    except KeyError:
        raise ValueError(
            f"unknown colour map {name!r}; choose one of {', '.join(COLORMAPS)}"
        ) from None
    lut = np.asarray(cmap.resampled(n)(np.arange(n)), dtype=np.float32)
    lut.setflags(write=False)
    return lut


def read_channel(recording, index: int, channel: int, quantity: Optional[str] = None) -> np.ndarray:
    """One channel of frame ``index`` as float32 (H, W) in ``quantity``
    (default: the stored one), converting only that channel."""
    stored = recording.frames(index, index + 1)[0, channel]
    if quantity is None or quantity == recording.quantity:
        return stored
    from qogi.radiometry import band_table

    table = band_table(recording.channels[channel])
    if quantity == "radiance":
        return table.radiance(stored)
    if quantity == "radiometric_temperature":
        return table.temperature(stored)
    raise ValueError(f"quantity must be 'radiance' or 'radiometric_temperature'; got {quantity!r}")


def robust_range(
    a: np.ndarray, percentiles: Tuple[float, float] = AUTO_PERCENTILES, step: int = 2
) -> Tuple[float, float]:
    """Low and high percentiles of the finite values of ``a`` (every ``step``-th
    pixel each way, for speed); a flat or empty image gets a unit-wide range."""
    sub = np.asarray(a)[::step, ::step] if np.ndim(a) == 2 else np.asarray(a)
    v = sub[np.isfinite(sub)]
    if v.size == 0:
        return 0.0, 1.0
    lo, hi = (float(x) for x in np.percentile(v, percentiles))
    if not hi > lo:
        half = max(abs(lo) * 1e-6, 1e-12)
        lo, hi = lo - half, hi + half
    return lo, hi


def recording_range(
    recording, channel: int, quantity: Optional[str] = None, samples: int = 12
) -> Tuple[float, float]:
    """Robust display range of one channel over the whole recording, from
    ``samples`` frames spread evenly over it (so playback does not flicker)."""
    n = recording.n_frames
    idx = np.unique(np.linspace(0, n - 1, min(samples, n)).round().astype(int))
    stack = np.stack([read_channel(recording, int(i), channel, quantity)[::2, ::2] for i in idx])
    return robust_range(stack.ravel(), step=1)


def colorize(
    a: np.ndarray,
    vmin: float,
    vmax: float,
    lut: np.ndarray,
    out: Optional[np.ndarray] = None,
    scratch: Optional[np.ndarray] = None,
) -> np.ndarray:
    """Map (H, W) values to RGBA float32 (H, W, 4) through ``lut``.

    Values at or below ``vmin`` get the first colour, at or above ``vmax`` the
    last; NaN (invalid) pixels are fully transparent. ``out`` (H, W, 4) float32
    and ``scratch`` (H, W) float32 may be given to avoid allocations.
    """
    a = np.asarray(a, dtype=np.float32)
    n = lut.shape[0]
    if scratch is None:
        scratch = np.empty(a.shape, np.float32)
    span = float(vmax) - float(vmin)
    scale = (n - 1) / span if span > 0 else 0.0
    np.subtract(a, np.float32(vmin), out=scratch)
    np.multiply(scratch, np.float32(scale), out=scratch)
    np.clip(scratch, 0, n - 1, out=scratch)
    bad = np.isnan(scratch)
    if bad.any():
        scratch[bad] = 0
    idx = scratch.astype(np.intp)
    if out is None:
        out = np.empty(a.shape + (4,), np.float32)
    np.take(lut, idx, axis=0, out=out)
    if bad.any():
        out[bad, 3] = 0.0
    return out


def colorize_overlay(
    a: np.ndarray,
    vmax: float,
    lut: np.ndarray,
    threshold: float = 0.03,
    opacity: float = 0.85,
    out: Optional[np.ndarray] = None,
) -> np.ndarray:
    """Column density (H, W) -> RGBA (H, W, 4) for drawing over the video.

    Colour from ``lut`` over [0, vmax]; opacity rises from 0 at
    ``threshold * vmax`` to ``opacity`` at ``vmax`` so gas-free pixels (and
    NaN, i.e. not quantified) leave the video visible.
    """
    a = np.asarray(a, dtype=np.float32)
    vmax = float(vmax) if vmax > 0 else 1.0
    out = colorize(np.nan_to_num(a, nan=0.0), 0.0, vmax, lut, out)
    frac = np.nan_to_num(a / np.float32(vmax), nan=0.0)
    alpha = np.clip((frac - threshold) / (1.0 - threshold), 0.0, 1.0) ** 0.5 * opacity
    out[..., 3] = alpha
    return out


def to_uint8_rgb(rgba: np.ndarray, background=(0.0, 0.0, 0.0)) -> np.ndarray:
    """RGBA float (H, W, 4) in [0, 1] over a background colour -> uint8 RGB (H, W, 3)."""
    rgb = rgba[..., :3] * rgba[..., 3:4] + np.asarray(background, np.float32) * (1 - rgba[..., 3:4])
    return np.clip(rgb * 255.0 + 0.5, 0, 255).astype(np.uint8)


def blend(under: np.ndarray, over: np.ndarray) -> np.ndarray:
    """Alpha-composite RGBA ``over`` onto RGBA ``under`` (both (H, W, 4) float)."""
    a = over[..., 3:4]
    out = under.copy()
    out[..., :3] = over[..., :3] * a + under[..., :3] * (1 - a)
    out[..., 3:4] = a + under[..., 3:4] * (1 - a)
    return out
