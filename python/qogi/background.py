"""The background that fits the scene (``QuantifyConfig.background="auto"``).

Two gas-free estimates of the band radiance behind the plume are available
(docs/pipeline_api.md): short strips **beside** each control surface
(interpolated along it), and a sign-aware temporal **percentile** of every
pixel. Beside-surface is exact for a static background of any smooth shape
when the strips are gas-free, and wrong by the gas's own contrast when they
are not (a surface shorter than the plume is wide; a wind-bent plume crossing
a vertical surface whose ends sit in the gas). The percentile needs no
strips but fails where the gas never leaves a pixel.

:func:`choose` checks the strips on a sample of the run's frames: a strip
that the gas visits shows a time-mean above its own low percentile (sign of
the gas contrast) by more than pure noise gives (for Gaussian noise
mean - p5 = 1.645 sigma; the threshold is 2.5 sigma, sigma from the strips'
own frame-to-frame noise floor) and fluctuations beyond the noise. When
every strip is gas-free the beside-surface background is used, else the
percentile; the choice and the evidence go into the result's ``info`` and
the budget gets a ``background`` term: the chosen estimate's uncertainty
(for the strips: the gas they may still hold beyond pure noise, and their
statistical error; for the percentile: its standard error and the gas it
still holds, its excess over the straight line between the surface's ends,
which also raises the warning ``background-not-gas-free``) relative to the
surface's mean contrast (a column changes in proportion to the contrast
where the plume is thin; more where it is thick).
"""

from __future__ import annotations

from typing import Dict, List, Sequence

import numpy as np

__all__ = ["choose", "strip_points", "GAS_EXCESS_SIGMA"]

#: (time mean - 5th percentile) / noise above which a strip carries gas
#: (pure Gaussian noise: 1.645).
GAS_EXCESS_SIGMA = 2.5
#: Excess of the percentile background over the straight line between the
#: surface's ends [noise] above which the percentile holds gas.
PERCENTILE_GAS_SIGMA = 5.0


def strip_points(points: np.ndarray, width: int, height: int) -> List[np.ndarray]:
    """The two strips' sample points (6 each, 2-7 px beyond the surface's
    ends along its end segments), as the beside-surface background takes
    them."""
    p = np.asarray(points, float)
    out = []
    for a, b in ((p[0], p[1]), (p[-1], p[-2])):
        d = (a - b) / np.hypot(*(a - b))
        pts = np.array([a + d * s for s in np.arange(2.0, 8.0, 1.0)])
        pts[:, 0] = np.clip(pts[:, 0], 0, width - 1)
        pts[:, 1] = np.clip(pts[:, 1], 0, height - 1)
        out.append(pts)
    return out


def _sample(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Nearest-pixel values of (..., H, W) at xy (N, 2) -> (..., N)."""
    x = np.clip(np.rint(xy[:, 0]).astype(int), 0, img.shape[-1] - 1)
    y = np.clip(np.rint(xy[:, 1]).astype(int), 0, img.shape[-2] - 1)
    return img[..., y, x]


def _noise(frames: np.ndarray) -> np.ndarray:
    """Per-channel pixel noise [radiance] (C,): the median over the image of
    the robust spread of frame-to-frame differences / sqrt(2) (motion of the
    gas raises it only where the gas is)."""
    d = np.diff(frames, axis=0)
    mad = np.median(np.abs(d - np.median(d, axis=0)), axis=0) * 1.4826 / np.sqrt(2.0)
    return np.median(mad.reshape(mad.shape[0], -1), axis=1)


def choose(
    frames: np.ndarray,
    surfaces: Sequence,
    samples: Sequence,
    channel_sign: np.ndarray,
    percentile: float = 5.0,
) -> Dict[str, object]:
    """The background for this scene from a sample of its frames.

    Parameters
    ----------
    frames : (T, C, H, W) radiance of (up to 50) frames spread over the run.
    surfaces : the control surfaces; samples : their ``(xy, n, dl, t)``.
    channel_sign : (C,) +1 where the gas raises the radiance, -1 where it
        lowers it.
    percentile : the percentile background's percentile.

    Returns
    -------
    dict with ``method`` ("beside-surface" or "percentile"), ``strips``
    (per surface: the worst strip's excess in noise units), ``reason`` and
    ``relative`` {surface index: the background term relative to the
    surface's mean contrast} and ``not_gas_free`` [(surface, excess in noise
    units)] where the percentile too holds gas.
    """
    f = np.asarray(frames, float)
    t, nc, h, w = f.shape
    sign = np.asarray(channel_sign, float)[:, None]
    noise = np.maximum(_noise(f), 1e-30)[:, None]  # (C, 1)
    lo_pct = np.where(sign >= 0, percentile, 100 - percentile)
    excess = []
    for s in surfaces:
        worst = 0.0
        for pts in strip_points(np.asarray(s.points), w, h):
            v = _sample(f, pts)  # (T, C, 6)
            mean = v.mean(axis=0)  # (C, 6)
            low = np.stack([np.percentile(v[:, c], lo_pct[c, 0], axis=0) for c in range(nc)])
            e = (sign * (mean - low) / noise).mean(axis=1)  # (C,)
            worst = max(worst, float(e.max()))
        excess.append(worst)
    beside_ok = t >= 5 and all(e <= GAS_EXCESS_SIGMA for e in excess)
    method = "beside-surface" if beside_ok or t < 5 else "percentile"
    # The chosen estimate's uncertainty at each surface, relative to the
    # surface's mean contrast (signal-weighted). Beside the surfaces: gas
    # the strips may still hold (their excess over pure noise's 1.645) and
    # their statistical error (6 pixels x T frames). The percentile: its
    # standard error (~1.3 sigma / sqrt(T) per pixel, along the surface).
    rel = {}
    not_free = []
    for j, (s, (xy, _n, _dl, tt)) in enumerate(zip(surfaces, samples)):
        at = _sample(f, xy)  # (T, C, N)
        if method == "beside-surface":
            ends = [
                _sample(f, pts).mean(axis=-1) for pts in strip_points(np.asarray(s.points), w, h)
            ]
            bg = (ends[0][..., None] * (1 - tt) + ends[1][..., None] * tt).mean(axis=0)
            delta = (max(0.0, excess[j] - 1.645) + 1.0 / np.sqrt(6.0 * t)) * noise[:, 0]
        else:
            bg = np.stack([np.percentile(at[:, c], lo_pct[c, 0], axis=0) for c in range(nc)])
            # Gas the percentile still holds (a plume that never leaves the
            # pixels): its excess over the straight line between the
            # surface's ends, averaged along the surface.
            line = bg[:, :1] * (1 - tt) + bg[:, -1:] * tt
            held = np.clip(sign * (bg - line), 0, None)  # (C, N)
            held_max = float((held / noise).max())
            if held_max > PERCENTILE_GAS_SIGMA:
                not_free.append((s.name or str(j), held_max))
            delta = 1.3 * noise[:, 0] / np.sqrt(t) + held.mean(axis=1)
        contrast = sign * (at.mean(axis=0) - bg)  # (C, N)
        weight = np.clip(contrast, 0, None)
        total = weight.sum(axis=1)  # (C,)
        if not total.max() > 0:
            rel[j] = 0.0
            continue
        c_best = int(np.argmax(total))
        mean_contrast = float((contrast[c_best] * weight[c_best]).sum() / total[c_best])
        rel[j] = float(delta[c_best] / max(mean_contrast, 1e-30))
    reason = (
        "the strips beside every surface are gas-free (time-mean within "
        f"{GAS_EXCESS_SIGMA} noise of their low percentile)"
        if beside_ok
        else "the strips beside surface(s) "
        + ", ".join(
            s.name or str(k)
            for k, (s, e) in enumerate(zip(surfaces, excess))
            if e > GAS_EXCESS_SIGMA
        )
        + " carry gas (time-mean above their low percentile "
        f"by up to {max(excess):.1f} noise): temporal percentile instead"
    )
    return {
        "method": method,
        "strips": [float(e) for e in excess],
        "reason": reason,
        "relative": rel,
        "not_gas_free": not_free,
    }
