"""Structured backgrounds for synthetic scenes: the blackbody behind the plume
as a per-pixel, optionally time-varying map of radiometric temperature.

Real scenes are not smooth (docs/synthetic.md, "Backgrounds with
structure"): a sky has a gradient, a fine static texture of tenths of a
kelvin and broken clouds that drift; a wall or tank has seams, bolts and a
shadow edge; a pipe rack has sharp hot and cold edges. Each is built here
in numpy, once per scene (the clouds' drift per frame, as an exact Fourier
shift of a periodic field twice the image's size); the renderer
(:mod:`qogi.synth.render`) passes the map to the engine's per-pixel radiative
transfer as each pixel's background temperature.

Maps are (H, W) float64 in K, pixel (row, column) with the origin at the
top-left pixel centre; every random element is drawn from ``seed``, so a
scene is reproducible and two seeds give two scenes of the same kind.

Examples
--------
>>> import numpy as np
>>> m = texture_field(64, 80, rms_K=0.3, correlation_px=4.0, seed=1)
>>> round(float(np.std(m)), 3)
0.3
"""

from __future__ import annotations

import math
from typing import Tuple

import numpy as np

__all__ = [
    "texture_field",
    "CloudField",
    "wall_features",
    "pipe_rack",
    "shadow_edge",
]


def _smooth_noise(height: int, width: int, correlation_px: float, rng) -> np.ndarray:
    """Periodic Gaussian-correlated noise of unit variance, (H, W): white
    noise filtered in Fourier space by a Gaussian of standard deviation
    ``correlation_px`` pixels (the field's correlation falls to exp(-1/4)
    at that lag)."""
    white = rng.standard_normal((height, width))
    ky = np.fft.fftfreq(height)[:, None]
    kx = np.fft.rfftfreq(width)[None, :]
    g = np.exp(-2.0 * (math.pi * correlation_px) ** 2 * (kx**2 + ky**2))
    f = np.fft.irfft2(np.fft.rfft2(white) * g, s=(height, width))
    sd = float(np.std(f))
    return (f - f.mean()) / sd if sd > 0 else f


def texture_field(
    height: int, width: int, rms_K: float, correlation_px: float, seed: int
) -> np.ndarray:
    """Static fine texture [K] of exactly ``rms_K`` RMS and zero mean, with a
    Gaussian correlation of ``correlation_px`` pixels (a sky's or a painted
    surface's small-scale structure: 0.1-0.5 K RMS, 2-20 px)."""
    if rms_K < 0 or not correlation_px > 0:
        raise ValueError(
            f"texture needs rms_K >= 0 and correlation_px > 0; got {rms_K}, {correlation_px}"
        )
    rng = np.random.default_rng([int(seed), 101])
    return rms_K * _smooth_noise(height, width, correlation_px, rng)


class CloudField:
    """Broken clouds drifting across the frame: warmer than the clear sky
    by up to ``contrast_K`` (a cloud's base radiates near the air's
    temperature aloft), with soft edges.

    A periodic smooth random field of twice the image's size (correlation
    ``size_px``) is shifted by the drift at each time exactly (Fourier
    shift theorem: sub-pixel, no interpolation, no border), then mapped to
    cloud amount 0-1 by a smoothstep around the quantile that leaves
    ``cover`` of the sky clouded; the smoothstep spans
    ``edge`` standard deviations of the field (soft edges a few pixels
    wide).

    Parameters
    ----------
    height, width : int
        Image size, px.
    contrast_K : float
        Temperature of a full cloud above the clear sky, K (> 0).
    cover : float
        Fraction of the sky clouded, in (0, 1).
    size_px : float
        Correlation length of the cloud field, px.
    drift_px_s : (float, float)
        Drift velocity (x right, y down), px/s.
    seed : int
    edge : float, default 0.6
    """

    def __init__(
        self,
        height: int,
        width: int,
        contrast_K: float,
        cover: float,
        size_px: float,
        drift_px_s: Tuple[float, float],
        seed: int,
        edge: float = 0.6,
    ):
        if not (0.0 < cover < 1.0 and size_px > 0 and edge > 0):
            raise ValueError(
                f"clouds need cover in (0, 1), size_px > 0 and edge > 0; "
                f"got {cover}, {size_px}, {edge}"
            )
        self.shape = (int(height), int(width))
        self.contrast_K = float(contrast_K)
        self.drift = (float(drift_px_s[0]), float(drift_px_s[1]))
        rng = np.random.default_rng([int(seed), 202])
        hc, wc = 2 * self.shape[0], 2 * self.shape[1]
        field = _smooth_noise(hc, wc, size_px, rng)
        self._spectrum = np.fft.rfft2(field)
        self._threshold = float(np.quantile(field, 1.0 - cover))
        self._edge = float(edge)
        self._ky = np.fft.fftfreq(hc)[:, None]
        self._kx = np.fft.rfftfreq(wc)[None, :]

    @property
    def static(self) -> bool:
        return self.drift == (0.0, 0.0)

    def amount(self, time_s: float) -> np.ndarray:
        """Cloud amount 0-1 of the image at ``time_s``, (H, W)."""
        dx, dy = self.drift[0] * time_s, self.drift[1] * time_s
        phase = np.exp(-2j * math.pi * (self._kx * dx + self._ky * dy))
        hc, wc = 2 * self.shape[0], 2 * self.shape[1]
        f = np.fft.irfft2(self._spectrum * phase, s=(hc, wc))[: self.shape[0], : self.shape[1]]
        u = np.clip((f - self._threshold) / self._edge + 0.5, 0.0, 1.0)
        return u * u * (3.0 - 2.0 * u)

    def temperature(self, time_s: float) -> np.ndarray:
        """The clouds' excess temperature [K] at ``time_s``, (H, W)."""
        return self.contrast_K * self.amount(time_s)


def shadow_edge(
    height: int, width: int, step_K: float, column: float, slope: float, soft_px: float = 1.0
) -> np.ndarray:
    """A shadow: ``-step_K`` [K] to the left of a straight edge through
    (``column``, top row) with ``slope`` px of x per px of y, ``soft_px``
    wide (the penumbra), 0 to its right."""
    y, x = np.mgrid[0:height, 0:width].astype(float)
    d = x - (column + slope * y)
    return -step_K * 0.5 * (1.0 - np.tanh(d / max(soft_px, 1e-6)))


def wall_features(
    height: int,
    width: int,
    seam_K: float,
    bolt_K: float,
    panel_px: float,
    seed: int,
) -> np.ndarray:
    """Seams and bolts of a cladded wall or tank [K], (H, W): vertical seams
    every ``panel_px`` and horizontal ones every 1.5 ``panel_px`` (2 px wide,
    ``-seam_K``: a joint's cavity is colder than the sunlit sheet), with
    bolts (2x2 px, ``+bolt_K``) every 12 px along the vertical seams. The
    panel grid's offset is drawn from ``seed``."""
    rng = np.random.default_rng([int(seed), 303])
    out = np.zeros((height, width))
    ox, oy = rng.uniform(0, panel_px, 2)
    for x in np.arange(ox, width, panel_px):
        c = int(x)
        out[:, c : c + 2] -= seam_K
        for y in np.arange(rng.uniform(0, 12), height, 12.0):
            r = int(y)
            out[r : r + 2, max(0, c - 2) : c] += bolt_K
            out[r : r + 2, c + 2 : c + 4] += bolt_K
    for y in np.arange(oy, height, 1.5 * panel_px):
        r = int(y)
        out[r : r + 2, :] -= seam_K
    return out


def pipe_rack(
    height: int,
    width: int,
    hot_K: float,
    cold_K: float,
    seed: int,
    n_horizontal: int = 4,
    n_vertical: int = 3,
) -> np.ndarray:
    """A pipe rack [K], (H, W): horizontal pipes and vertical supports with
    sharp edges, alternately ``+hot_K`` (steam, hot product) and
    ``-cold_K`` (chilled lines) against the structure behind them, each
    4-12 px wide with a cylinder's brightness across it (the limb at 70 %
    of the centre's excess); positions and widths drawn from ``seed``."""
    rng = np.random.default_rng([int(seed), 404])
    out = np.zeros((height, width))
    k = 0
    for n, size, axis in ((n_horizontal, height, 0), (n_vertical, width, 1)):
        for c in rng.uniform(0.08, 0.92, n) * size:
            half = 0.5 * rng.uniform(4.0, 12.0)
            delta = hot_K if k % 2 == 0 else -cold_K
            k += 1
            coord = np.arange(size, dtype=float)
            r = np.abs(coord - c) / half
            profile = np.where(r <= 1.0, delta * (0.7 + 0.3 * np.sqrt(np.clip(1 - r * r, 0, 1))), 0)
            sel = r <= 1.0
            if axis == 0:  # a horizontal pipe: occludes what is behind it
                out[sel, :] = profile[sel, None]
            else:
                out[:, sel] = profile[None, sel]
    return out
