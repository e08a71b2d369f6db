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
own frame-to-frame noise floor) and fluctuations beyond the noise. It also
measures the background's own structure along each surface (on its
gas-free samples, the time-mean's RMS departure from the beside-surface
background against the gas's sign, which gas cannot cause, times sqrt 2;
in noise): a textured sky, a wall's seams or a pipe's edge make the
straight line between the strips wrong by their contrast (issue 31: -36 %
on an outdoor release). When every strip is gas-free and no surface has
structure beyond :data:`STRUCTURE_SIGMA`, the beside-surface background is
used, else the percentile, whose pixels the gas never leaves are filled
from their gas-free neighbours (:func:`inpaint_held`: the percentile's
residual about a smooth surface inpainted, i.e. the structure, not the raw
radiance). The choice and the evidence go into the result's ``info`` and
the budget gets a ``background`` term: the chosen estimate's uncertainty
(for the strips: the gas they may still hold beyond pure noise, and their
statistical error; for the percentile: its standard error and, on the
fraction of the surface the gas never leaves, the background's structure,
which above :data:`HELD_WARN_FRACTION` also raises the warning
``background-not-gas-free``) relative to the surface's mean contrast (a
column changes in proportion to the contrast where the plume is thin; more
where it is thick).
"""

from __future__ import annotations

from statistics import NormalDist
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

from .. import _engine

__all__ = [
    "choose",
    "drift_evidence",
    "DRIFT_SIGMA",
    "strip_points",
    "inpaint_held",
    "pixel_sign",
    "percentile_background",
    "GAS_EXCESS_SIGMA",
    "STRUCTURE_SIGMA",
    "HELD_SPREAD_SIGMA",
    "held_background_error",
    "HELD_RING_GAP_PX",
    "HELD_RING_PX",
    "standing_from_source",
]

#: (time mean - 5th percentile) / noise above which a strip carries gas
#: (pure Gaussian noise: 1.645).
GAS_EXCESS_SIGMA = 2.5
#: RMS departure [noise] of the background along a surface's samples
#: where it is seen (:func:`_structure`) from the straight line between the
#: strips above which the
#: background has structure that the strips beside the surface miss (a
#: textured sky, a wall's seams): then the temporal percentile. A smooth sky
#: gives the time-mean's own noise, ~0.15 with 50 frames.
STRUCTURE_SIGMA = 3.0
#: The background's own drift over the run [noise] (:func:`drift_evidence`)
#: above which it moves on its own (clouds drifting across a sky) and
#: ``auto`` takes the drifting background. A still background gives
#: 0.9-1.0 (the spread of four windows' percentiles of noise alone; 1.9 at
#: the 90th percentile of pixels); the clouds preset 190 (seed 0).
DRIFT_SIGMA = 5.0
#: Windows of consecutive frames the drift evidence compares.
DRIFT_WINDOWS = 4
#: Fraction of a surface's samples the gas never leaves above which the
#: warning ``background-not-gas-free`` says the percentile background there
#: is filled from the neighbours.
HELD_WARN_FRACTION = 0.5


def drift_evidence(frames: np.ndarray, channel_sign: np.ndarray, percentile: float = 5.0) -> float:
    """The background's own drift over the run, in noise units.

    The frames (T, C, H, W), in time order, are cut into
    :data:`DRIFT_WINDOWS` windows of consecutive frames; in each, every
    pixel's sign-aware low percentile (the ``percentile``-th where the gas
    raises the radiance, the ``100 - percentile``-th where it lowers it: the
    background with the gas left out, as the temporal percentile takes it).
    A pixel's drift is the range of its windows' percentiles over the
    channel's noise (:func:`_noise`); the evidence is the median over the
    image's pixels (the plume covers a minority of them, and a pixel whose
    gas stays a whole window is an outlier of that median), the largest
    over the channels. A still background gives the percentiles' own
    scatter, about 1; a cloud drifting through a pixel its contrast, tens to
    hundreds. 0 with fewer than 2 frames per window.
    """
    f = np.asarray(frames, float)
    t, nc = f.shape[:2]
    if t < 2 * DRIFT_WINDOWS:
        return 0.0
    sign = np.asarray(channel_sign, float)
    noise = np.maximum(_noise(f), 1e-30)
    worst = 0.0
    for c in range(nc):
        q = percentile if sign[c] >= 0 else 100.0 - percentile
        lows = np.stack(
            [np.percentile(f[i, c], q, axis=0) for i in np.array_split(np.arange(t), DRIFT_WINDOWS)]
        )
        spread = (lows.max(axis=0) - lows.min(axis=0)) / noise[c]
        worst = max(worst, float(np.median(spread)))
    return worst


def _structure(f, surface, xy, tt, sign, noise, lo_pct) -> float:
    """The background's own structure along a surface [noise]: sqrt(2) x
    the RMS departure, against the gas's sign, of the background from the
    beside-surface background (the straight line between the strips beside
    the surface's ends), in the most departing channel, on the samples whose
    background is seen:

    * the gas-free samples (time-mean within :data:`GAS_EXCESS_SIGMA` noise
      of their low percentile, as the strips are tested): their time-mean;
    * the samples the gas visits but leaves often enough (not gas-free, and
      not held by the spread test of :func:`inpaint_held`): their low
      percentile, against the line between the strips' own low percentiles
      (the noise's percentile is in both). A seam under the plume's path is
      only there (``tank-emission`` seed 3: 0.0 / 0.5 / 2.0 on the gas-free
      samples, 13 / 15 / 3 with these; the strips read -69 to -76 %).

    0 with fewer than 4 gas-free samples (nothing to measure; on a
    noise-free test scene whose gas covers the whole surface the visited
    samples' nearest-pixel staircase along a gradient read 296 "noise").
    Gas can only raise the time-mean and the low percentile, a
    background's structure departs both ways, so the one side measures
    it."""
    v = _sample(f, xy)  # (T, C, N)
    mean = v.mean(axis=0)  # (C, N)
    nc = v.shape[1]
    low = np.stack([np.percentile(v[:, c], lo_pct[c, 0], axis=0) for c in range(nc)])
    q2 = np.where(lo_pct <= 50.0, 2.0 * lo_pct, 100.0 - 2.0 * (100.0 - lo_pct))
    low2 = np.stack([np.percentile(v[:, c], q2[c, 0], axis=0) for c in range(nc)])
    free = ((sign * (mean - low) / noise) <= GAS_EXCESS_SIGMA).all(axis=0)  # (N,)
    held = (sign * (low2 - low) / noise > HELD_SPREAD_SIGMA).any(axis=0)
    if free.sum() < 4:
        return 0.0
    visited = ~free & ~held
    h, w = f.shape[-2:]
    strips = [_sample(f, pts) for pts in strip_points(surface.points, w, h)]  # (T, C, 6)

    def line(ends):
        return ends[0][:, None] * (1 - tt)[None, :] + ends[1][:, None] * tt[None, :]

    # The time-means against the line between the strips' time-means, the
    # low percentiles against the line between the strips' own low
    # percentiles (the noise's percentile and whatever gas the strips hold
    # are in both).
    mean_line = line([v_.mean(axis=(0, -1)) for v_ in strips])
    low_line = line(
        [
            np.array([np.percentile(v_[:, c], lo_pct[c, 0], axis=0).mean() for c in range(nc)])
            for v_ in strips
        ]
    )
    dev = np.concatenate(
        [
            np.minimum(0.0, sign * (mean - mean_line))[:, free] / noise,
            np.minimum(0.0, sign * (low - low_line))[:, visited] / noise,
        ],
        axis=1,
    )
    return float(np.sqrt(2.0 * np.mean(dev**2, axis=1)).max())


#: Spread [noise] between the temporal percentile and twice that
#: percentile of a pixel above which the gas never leaves it often enough
#: for the percentile to be its background (pure noise: 0.36 for the 5th
#: and 10th; the estimates' own scatter over 150 frames ~0.25).
HELD_SPREAD_SIGMA = 1.5
#: The ring of gas-free pixels on which :func:`held_background_error` tries
#: the held pixels' inpainting: from HELD_RING_GAP_PX beyond the held region
#: (nearer, the gas biases the percentile: on the laminar lab column a ring
#: touching the held pixels read 0.5-1.7 of the gas's contrast, from 4 px
#: out 0.08-0.29) to HELD_RING_GAP_PX + HELD_RING_PX.
HELD_RING_GAP_PX = 4
HELD_RING_PX = 3
#: The steady core (:func:`standing_from_source`): a pixel whose percentile
#: stands above the median of its neighbourhood (STANDING_SCALE_PX across)
#: in the gas's sign by STANDING_SEED_SIGMA of the image's own structure (the
#: MAD of that residual over the image: texture, seams, noise) seeds it; the
#: seeds' region grows over pixels above STANDING_GROW_SIGMA and is widened
#: by STANDING_MARGIN_PX (the core's faint edge below the threshold).
#: Before the seeds are sought, the region is opened by a disk of
#: STANDING_OPEN_PX: a wall's seams stand out as much as a core and run
#: through the source's neighbourhood (the wall preset's seam grid is one
#: region over the whole frame, its seed 0 read +334 % when inpainted),
#: but they are lines 1-3 px wide, the core near a source 10-20 px.
#: The seed threshold was 6 at first: on the textured lab over a plate of
#: twice the preset's texture (0.6 K) the core stands 3-5.5 times the
#: structure and was not found; at 4 it is, and the held regions of
#: every validation case's seed 0 are the same pixels at 4, 5 and 6 (a
#: texture's 4-sigma peak within 6 px of the source is rare: 3e-5 of the
#: pixels).
STANDING_SCALE_PX = 30
STANDING_OPEN_PX = 2
STANDING_SEED_SIGMA = 4.0
STANDING_GROW_SIGMA = 2.0
STANDING_MARGIN_PX = 2


def pixel_sign(
    median: np.ndarray, gas_radiance: np.ndarray, channel_sign: np.ndarray
) -> np.ndarray:
    """The gas's sign per pixel and channel (C, ...): +1 where a gas at
    band radiance ``gas_radiance`` (C,) [W/(m2 sr)] raises the pixel's
    radiance (the background is colder than the gas), -1 where it lowers it
    (a hot pipe behind a plume that emits elsewhere), from the pixel's
    temporal ``median`` (C, ...) (its background where the gas is there
    less than half the time; or the background itself; thesis eq. 4: the contrast is
    tau (L(T_gas) - L_bg)). Where the median is within a tenth of the
    typical contrast of the gas's radiance (the gas nearly invisible) the
    channel's sign ``channel_sign`` (C,) is kept."""
    med = np.asarray(median, float)
    tail = (1,) * (med.ndim - 1)
    lg = np.asarray(gas_radiance, float).reshape((-1,) + tail)
    sign = np.asarray(channel_sign, float).reshape((-1,) + tail)
    den = lg - med
    typical = np.abs(np.median(den.reshape(den.shape[0], -1), axis=1))[:, None, None]
    return np.where(np.abs(den) > 0.1 * typical, np.sign(den), sign) * np.ones_like(med)


def percentile_background(
    stacked: np.ndarray,
    channel_sign: np.ndarray,
    percentile: float,
    gas_radiance=None,
    noise: Optional[np.ndarray] = None,
    source_xy: Optional[Tuple[float, float]] = None,
    return_clip: bool = False,
):
    """The sign-aware temporal percentile background (C, h, w) of frames
    ``stacked`` (T, C, h, w) and its held pixels (:func:`inpaint_held`):
    per pixel the low ``percentile`` where the gas raises the radiance, the
    high one where it lowers it. The sign is the channel's
    ``channel_sign`` (C,), or with ``gas_radiance`` (C,) [W/(m2 sr)] given,
    each pixel's own (:func:`pixel_sign`): a gas that emits in front of a
    cold wall absorbs in front of a pipe hotter than itself, and one sign
    for the channel takes the gas's own frames as the hot pipe's
    background. ``noise`` (C,): the channels' noise, when the caller has
    it (:func:`_noise` of ``stacked`` otherwise). ``source_xy`` (x, y)
    [px, the image's coordinates]: the source, when known, whose steady
    core is held too (:func:`standing_from_source`). ``return_clip``: the
    inpainting's clip too (:func:`inpaint_held`)."""
    lo, med, hi = temporal_percentiles(stacked, (percentile, 50.0, 100 - percentile))
    sign = np.asarray(channel_sign, float)
    sign = (
        np.broadcast_to(sign[:, None, None], med.shape)
        if gas_radiance is None
        else pixel_sign(med, gas_radiance, sign)
    )
    img = np.where(sign >= 0, lo, hi)
    # Where the gas never leaves a pixel, its percentile holds gas: the
    # background's structure there from the free neighbours.
    return inpaint_held(
        stacked,
        img,
        sign,
        percentile,
        noise,
        source_xy=source_xy,
        only_from_source=False,
        return_clip=return_clip,
    )


def inpaint_held(
    stacked: np.ndarray,
    img: np.ndarray,
    channel_sign: np.ndarray,
    percentile: float,
    noise: Optional[np.ndarray] = None,
    source_xy: Optional[Tuple[float, float]] = None,
    only_from_source: bool = True,
    return_clip: bool = False,
):
    """The temporal percentile background ``img`` (C, h, w) of frames
    ``stacked`` (T, C, h, w), with the pixels the gas never leaves filled
    from their gas-free neighbours: their *residual* about a smooth
    quadratic surface fitted to the other pixels (the background's
    structure: texture, seams, edges) inpainted (Bertalmio's Navier-Stokes
    method, OpenCV's, in the engine: ``_engine.inpaint_ns``) and added back to the
    surface there.

    A pixel is held when, in any channel, the sign-aware spread between its
    ``2 x percentile`` and ``percentile`` values exceeds
    :data:`HELD_SPREAD_SIGMA` noise (gas present in nearly every frame
    lifts the low tail and widens it; noise alone does not).

    ``channel_sign`` is (C,), or (C, h, w) per pixel (:func:`pixel_sign`).

    With ``source_xy`` (x, y) [px, the image's coordinates] the steady core
    the gas fills without fluctuating, which the spread test cannot see
    (:func:`standing_from_source`), is held too; with ``only_from_source``
    only the spread test's parts connected to the source are kept
    (:func:`held_from_source`).

    The inpainting is bounded by the percentile: gas moves a pixel's
    radiance in its own sign only, so a held pixel's background lies on the
    other side of its percentile (less the noise's own percentile).

    Returns ``(background (C, h, w), held (h, w) bool)``; the input image
    when no pixel is held or fewer than a quarter are free. With
    ``return_clip`` also the bound's clip (C, h, w) [radiance, >= 0]: by
    how much the inpainting stood beyond the bound, i.e. by how much the
    background there contradicts the frames, as far as they show it (the
    background residual's evidence, :mod:`qogi.pipeline.selfchecks`).
    """
    f = np.asarray(stacked, np.float32)
    nc = f.shape[1]
    sign = np.asarray(channel_sign, float)
    if sign.ndim == 1:
        sign = sign[:, None, None]
    sign = np.broadcast_to(sign, img.shape)
    noise = np.maximum(_noise(f) if noise is None else np.asarray(noise, float), 1e-30)
    held = np.zeros(img.shape[1:], bool)
    for c in range(nc):
        lo1, lo2, hi2, hi1 = temporal_percentiles(
            f[:, c], (percentile, 2.0 * percentile, 100 - 2 * percentile, 100 - percentile)
        )
        spread = np.where(sign[c] >= 0, lo2 - lo1, hi1 - hi2)
        held |= spread > HELD_SPREAD_SIGMA * noise[c]
    if source_xy is not None:
        if only_from_source and held.any():
            held = held_from_source(held, source_xy)
        held |= standing_from_source(img, sign, noise, source_xy)
    clip = np.zeros(img.shape, np.float32)
    if not held.any() or (~held).sum() < 0.25 * held.size:
        return (img, held, clip) if return_clip else (img, held)
    out = np.array(img, dtype=float, copy=True)
    # Gas moves a pixel's radiance in its own sign only, so its background
    # lies on the other side of its percentile (less the noise's own
    # percentile): an inpainting beyond it (a hot pipe under the plume
    # filled from the cold sky around it) is bounded there.
    tail = -NormalDist().inv_cdf(min(percentile, 100.0 - percentile) / 100.0)
    for c in range(nc):
        filled = _inpaint_structure(out[c], held, float(noise[c]))
        limit = sign[c] * img[c] + tail * noise[c]
        clip[c] = np.maximum(0.0, sign[c] * filled - limit)
        out[c] = sign[c] * np.minimum(sign[c] * filled, limit)
    out = out.astype(img.dtype, copy=False)
    return (out, held, clip) if return_clip else (out, held)


def held_from_source(held: np.ndarray, source_xy, radius_px: float = 6.0) -> np.ndarray:
    """The parts of a ``held`` mask (h, w) bool connected to the source: its
    8-connected components with a pixel within ``radius_px`` of
    ``source_xy`` (x, y) [px, the mask's coordinates]. The gas never leaves
    the plume's base, which starts at the source; elsewhere a held pixel
    may be a background that changes for another reason (a drifting cloud's
    edge the drifting layer did not follow), whose static structure the
    inpainting would smooth away."""
    held = np.asarray(held, bool)
    labels = _engine.connected_components8(held.astype(np.uint8))
    h, w = held.shape
    y, x = np.mgrid[0:h, 0:w]
    near = (x - source_xy[0]) ** 2 + (y - source_xy[1]) ** 2 <= radius_px**2
    keep = np.unique(labels[near & held])
    return np.isin(labels, keep[keep > 0])


def standing_from_source(
    img: np.ndarray, sign: np.ndarray, noise: np.ndarray, source_xy
) -> np.ndarray:
    """The plume's steady core in a temporal percentile image ``img``
    (C, h, w): (h, w) bool.

    Near the source of a quiet release the gas fills the same pixels in
    every frame with nearly the same column: their percentile is the
    background plus the gas, and it hardly spreads (the lab release in front
    of a textured plate: 2 and 4 cm above the exit, 5th to 10th percentile
    within 1 noise, the gas's contrast 170-220 noise, docs/validation.md).
    What shows it is space, not time: the core stands above its
    neighbourhood, in the gas's sign, by far more than the background's own
    structure does.

    Per channel, the residual of ``img`` about the median of its
    neighbourhood (:data:`STANDING_SCALE_PX` across, taken at half
    resolution), signed by the gas's ``sign`` (C, h, w) and scaled by its
    MAD over the image (the texture's, seams' and noise's size); the regions
    above :data:`STANDING_GROW_SIGMA`, less their lines narrower than
    :data:`STANDING_OPEN_PX` (a morphological opening: seams), that hold a
    pixel above
    :data:`STANDING_SEED_SIGMA` and reach within 6 px of ``source_xy``
    (x, y) [px] (:func:`held_from_source`), widened by
    :data:`STANDING_MARGIN_PX`. ``noise`` (C,) is unused beyond keeping the
    scale away from zero on a noiseless image."""
    im = np.asarray(img, float)
    nc, h, w = im.shape
    out: np.ndarray = np.zeros((h, w), bool)
    if h < 8 or w < 8:
        return out
    size = max(3, STANDING_SCALE_PX // 2)
    for c in range(nc):
        half = _engine.resize_image(im[c].astype(np.float32), (w + 1) // 2, (h + 1) // 2, "area")
        local = _engine.resize_image(_median_filter(half, size), w, h, "linear")
        r = np.asarray(sign[c], float) * (im[c] - local)
        scale = max(1.4826 * float(np.median(np.abs(r - np.median(r)))), 1e-3 * float(noise[c]))
        seeds = r > STANDING_SEED_SIGMA * scale
        if not seeds.any():
            continue
        grown = _engine.open_disk(
            (r > STANDING_GROW_SIGMA * scale).astype(np.uint8), STANDING_OPEN_PX
        )
        labels = _engine.connected_components8(grown)
        keep = np.unique(labels[seeds & (grown > 0)])
        out |= held_from_source(np.isin(labels, keep[keep > 0]), source_xy)
    if out.any() and STANDING_MARGIN_PX:
        out = _engine.dilate_disk(out.astype(np.uint8), STANDING_MARGIN_PX).astype(bool)
    return out


def _median_filter(image: np.ndarray, size: int) -> np.ndarray:
    """The median of each pixel's ``size`` x ``size`` neighbourhood of
    ``image`` (h, w), the border repeated (float32)."""
    r = size // 2
    padded = np.pad(np.asarray(image, np.float32), r, mode="edge")
    win = np.lib.stride_tricks.sliding_window_view(padded, (size, size))
    return np.median(win.reshape(win.shape[0], win.shape[1], -1), axis=-1).astype(np.float32)


def _inpaint_structure(image: np.ndarray, mask: np.ndarray, noise: float) -> np.ndarray:
    """``image`` (h, w) with its ``mask`` pixels filled from the others: a
    smooth quadratic surface fitted to the unmasked pixels, plus their
    residual about it inpainted into the mask (Navier-Stokes,
    ``_engine.inpaint_ns``)."""
    h, w = mask.shape
    y, x = np.mgrid[0:h, 0:w]
    xs, ys = (x.ravel() - 0.5 * w) / w, (y.ravel() - 0.5 * h) / h
    basis = np.stack([np.ones_like(xs), xs, ys, xs * xs, xs * ys, ys * ys], axis=1)
    free = ~mask.ravel()
    im = np.asarray(image, float)
    coef, *_ = np.linalg.lstsq(basis[free], im.ravel()[free], rcond=None)
    smooth = (basis @ coef).reshape(h, w)
    # In noise units: OpenCV's inpainting of float images is made for
    # values of order one and more (Telea's method fails on radiances
    # of 1e-3; Navier-Stokes holds at any scale once so scaled).
    resid = ((im - smooth) / noise).astype(np.float32)
    filled = _engine.inpaint_ns(resid, mask.astype(np.uint8), 3.0).astype(float) * noise
    return np.where(mask, smooth + filled, im)


def held_background_error(
    stacked: np.ndarray,
    background: np.ndarray,
    held: np.ndarray,
    noise: Optional[np.ndarray] = None,
    gap_px: int = HELD_RING_GAP_PX,
    ring_px: int = HELD_RING_PX,
) -> float:
    """How wrong the inpainted background of the held pixels (the gas never
    leaves them: the plume's core near the source) may be, relative to the
    gas's contrast there (a float; NaN with no held pixel, or too few free
    ones to test on).

    The inpainting is tried where the answer is known: a ring of gas-free
    pixels ``gap_px`` to ``gap_px + ring_px`` beyond the held region (the
    first ``gap_px`` left out: the gas reaches them often enough to bias
    their percentile) is filled as the held pixels are, from the pixels
    beyond it (:func:`_inpaint_structure`), and compared with the
    background there. Its RMS error [noise] over the held pixels' median
    contrast ``|median frame - background|`` [noise], in the channel where
    that contrast is largest, is returned: 0.1-0.3 on a textured sky and a
    tank, 0.4-1.6 on a wall whose seams and shadow edge run under the
    plume's base, 0.9-4.4 across a pipe rack (docs/validation.md). Above
    1 the background under the plume's base is not known to better than
    the gas's own contrast, and neither are the columns there, which the
    flux level follows along the whole plume (``background-held``).

    ``stacked`` (T, C, h, w) the frames the background was taken on,
    ``background`` (C, h, w) the background with the held pixels
    inpainted (:func:`inpaint_held`), ``held`` (h, w) bool; ``noise`` (C,)
    the channels' noise (:func:`_noise` of ``stacked`` when not given)."""
    held = np.asarray(held, bool)
    if not held.any():
        return float("nan")
    inner = _engine.dilate_disk(held.astype(np.uint8), gap_px).astype(bool) if gap_px else held
    outer = _engine.dilate_disk(held.astype(np.uint8), gap_px + ring_px).astype(bool)
    ring = outer & ~inner
    if not ring.any() or (~outer).sum() < 0.25 * outer.size:
        return float("nan")
    f = np.asarray(stacked, np.float32)
    noise = np.maximum(_noise(f) if noise is None else np.asarray(noise, float), 1e-30)
    best = (-1.0, float("nan"))
    for c in range(f.shape[1]):
        bg = np.asarray(background[c], float)
        med = np.median(f[:, c][:, held], axis=0)  # the held pixels' only
        contrast = float(np.median(np.abs(med - bg[held]))) / noise[c]
        if contrast > best[0]:
            err = (_inpaint_structure(bg, outer, float(noise[c])) - bg)[ring] / noise[c]
            rms = float(np.sqrt(np.mean(err * err)))
            best = (contrast, rms / contrast if contrast > 0 else float("inf"))
    return best[1]


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


def temporal_percentiles(frames: np.ndarray, q) -> np.ndarray:
    """``np.percentile(frames, q, axis=0)`` computed by the engine
    (``_engine.temporal_percentiles``: the same values, a few hundred pixels'
    series at a time, so that no copy of the frames is made): (len(q), ...)
    of a (T, ..., h, w) float32 or float64 stack."""
    return _engine.temporal_percentiles(np.asarray(frames), [float(v) for v in q])


def _noise(frames: np.ndarray) -> np.ndarray:
    """Per-channel pixel noise [radiance] (C,): the median over the image of
    the robust spread of frame-to-frame differences / sqrt(2) (motion of the
    gas raises it only where the gas is); the spread per pixel by the engine
    (``_engine.difference_spread``: numpy's median absolute deviation of the
    differences, the same values, no copy of the frames)."""
    raw = _engine.difference_spread(np.asarray(frames))
    mad = raw * 1.4826 / np.sqrt(2.0)
    return np.median(mad.reshape(mad.shape[0], -1), axis=1)


def _relative_to_contrast(delta: np.ndarray, contrast: np.ndarray) -> float:
    """A background's uncertainty relative to the surface's contrast: ``delta``
    (C,) of the channel whose positive contrast (C, N) sums highest, over that
    channel's contrast-weighted mean contrast; 0 where no channel sees gas."""
    weight = np.clip(contrast, 0, None)
    total = weight.sum(axis=1)  # (C,)
    if not total.max() > 0:
        return 0.0
    c = int(np.argmax(total))
    mean_contrast = float((contrast[c] * weight[c]).sum() / total[c])
    return float(delta[c] / max(mean_contrast, 1e-30))


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
    dict with ``method`` ("beside-surface", "percentile" or "drifting":
    the background's own drift, :func:`drift_evidence`, beyond
    :data:`DRIFT_SIGMA`), ``drift`` (that evidence, noise), ``strips``
    (per surface: the worst strip's excess in noise units), ``reason`` and
    ``relative`` {surface index: the background term relative to the
    surface's mean contrast}, ``structure`` (per surface: the background's
    own structure along its gas-free samples, noise) and ``not_gas_free``
    [(surface, fraction of its samples the gas never leaves)] where that
    fraction exceeds :data:`HELD_WARN_FRACTION`.
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
    strips_ok = t >= 5 and all(e <= GAS_EXCESS_SIGMA for e in excess)
    drift = drift_evidence(f, channel_sign, percentile)
    structure = [
        _structure(f, s, xy, tt, sign, noise, lo_pct)
        for s, (xy, _n, _dl, tt) in zip(surfaces, samples)
    ]
    textured = [
        s.name or str(k) for k, (s, v) in enumerate(zip(surfaces, structure)) if v > STRUCTURE_SIGMA
    ]
    beside_ok = strips_ok and not textured
    if not beside_ok and drift > DRIFT_SIGMA:
        # The background moves on its own: where the strips beside the
        # surfaces are gas-free and the background straight between them,
        # the beside-surface background (per frame) holds whatever moves
        # elsewhere (a warm blob sweeping a small view is no cloud); else
        # neither the strips (they see the clouds as they pass) nor a
        # percentile over the whole run (it takes the clear sky under a
        # cloud) hold, and the drifting background follows it (its budget
        # term is set once it is made: the stage's drifting_relative).
        return {
            "method": "drifting",
            "strips": [float(e) for e in excess],
            "structure": [float(v) for v in structure],
            "drift": drift,
            "reason": (
                f"the background drifts on its own (its low percentile moves by {drift:.1f} "
                f"noise between windows of the run, median over the image; a still one "
                f"within {DRIFT_SIGMA:g}): a static and a drifting layer, the drift measured "
                "apart from the gas"
            ),
            "relative": {},
            "not_gas_free": [],
        }
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
            # Samples the gas never leaves (the spread test of
            # inpaint_held): their background is filled from the gas-free
            # neighbours, uncertain by the background's own structure (at
            # least the noise).
            q2 = np.where(sign >= 0, 2 * percentile, 100 - 2 * percentile)
            bg2 = np.stack([np.percentile(at[:, c], q2[c, 0], axis=0) for c in range(nc)])
            held = (sign * (bg2 - bg) / noise > HELD_SPREAD_SIGMA).any(axis=0)  # (N,)
            held_fraction = float(held.mean())
            if held_fraction > HELD_WARN_FRACTION:
                not_free.append((s.name or str(j), held_fraction))
            delta = (1.3 / np.sqrt(t) + held_fraction * max(1.0, structure[j])) * noise[:, 0]
        rel[j] = _relative_to_contrast(delta, sign * (at.mean(axis=0) - bg))
    reason = (
        "the strips beside every surface are gas-free (time-mean within "
        f"{GAS_EXCESS_SIGMA} noise of their low percentile) and the background is "
        f"straight between them (its structure within {STRUCTURE_SIGMA:g} noise)"
        if beside_ok
        else "the background along surface(s) "
        + ", ".join(textured)
        + f" has structure a straight line between the strips misses (up to "
        f"{max(structure):.1f} noise RMS on the surface's gas-free pixels): temporal "
        "percentile instead"
        if strips_ok
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
        "structure": [float(v) for v in structure],
        "drift": drift,
        "reason": reason,
        "relative": rel,
        "not_gas_free": not_free,
    }
