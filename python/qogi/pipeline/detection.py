"""Detection limit: the smallest emission rate a scene lets qogi detect.

Per pixel, the camera's noise (NETD, K) is a radiance noise
``n_c = NETD dB_c/dT(T_bg)`` per channel; a thin plume of column density
``c`` [kg/m2] changes the band radiance by ``s_c c`` with ``s_c`` set by the
background contrast and the gas temperature (the forward model in its thin
limit). The **noise-equivalent column** is the column whose signal equals the
noise, combined over channels as the least-squares estimate would:
``NEC = (sum_c (s_c / n_c)^2)^(-1/2)``.

The **detection limit** of a control surface: the pipeline counts a pixel's
column only when its contrast exceeds ``k`` noise in some channel (the
inversion's per-pixel test, ``detection_sigma`` = 3), so a plume crossing a
surface is seen in a frame when its peak column there exceeds ``k NEC``
(NEC of the most sensitive channel, as the test is per channel). To be seen
in a fraction ``confidence`` of the frames, the peak must exceed the
threshold by a further ``z NEC`` (``z`` the one-sided normal quantile of
``confidence``; Currie's detection limit, L. A. Currie, Anal. Chem. 40 (1968)
586, with the decision threshold at ``k`` noise). The flux of a plume is
``F = v c_peak w`` (thesis eq. 12 summed across the plume) with ``w = sum c dl /
c_peak`` its effective width along the surface [m], so the smallest
detectable rate is

    ``F_min = (k + z) NEC v w``

with ``v`` the measured gas speed normal to the surface (column-weighted) and
``w`` the measured effective width: of the time-averaged contrast profile
along the surface when its peak is significant among all the surface's
samples (:func:`significant_peak`; its noise is sqrt(frames) lower than a
frame's, and it shows the plume's wings that a frame's thresholded columns
cut off). Where the time average shows no plume, ``w`` is the surface's
length (the widest plume the surface can hold: the limit is then an upper
bound, not a width made of noise); the median width over the frames that
saw gas only when no time average is at hand. Without gas, ``v`` is the median
normal speed the run used. ``docs/validation/detection_limit.md`` compares it with the
pipeline's detections on a synthetic sweep and with Zeng and Morris's GF320
fit.

The **minimum-detectable column** per pixel, ``(k + z) NEC(T_bg)`` at each
pixel's own background temperature (:func:`min_detectable_column`), is the
column a pixel must hold to be seen in a fraction ``confidence`` of the
frames: the map of where in the frame the camera can see this gas at all.
"""

from __future__ import annotations

import math
import warnings
from statistics import NormalDist
from typing import Optional

import numpy as np

from ..physics.radiometry import band_table

__all__ = [
    "CONFIDENCE",
    "DETECTION_SIGMA",
    "noise_equivalent_column",
    "min_detectable_column",
    "median_background_K",
    "detection_limit_kg_s",
    "effective_width",
    "normal_velocity",
    "surface_detection_limit",
    "zeng_morris_g_h",
]

#: Default confidence of the detection limit: 5 % false positives and 5 %
#: missed detections at the limit.
CONFIDENCE = 0.95
#: The pipeline's per-pixel detection test |contrast| >= k noise
#: (``qogi.inversion``'s ``detection_sigma``).
DETECTION_SIGMA = 3.0
#: Thin-limit probe: a peak volume fraction small enough that the band
#: radiance is linear in it (optical depth << 1 in every band).
_PROBE_FRACTION = 1e-5


def noise_equivalent_column(
    model,
    species: str,
    netd_K,
    background_K: float,
    gas_K: float,
    ambient_K: float,
    sigma_m: float = 0.05,
) -> float:
    """Column density [kg/m2] whose band-radiance signal equals the camera's
    1-sigma noise in one pixel and one frame, in the most sensitive channel
    (thin limit).

    Parameters
    ----------
    model : qogi.physics.forward.ForwardModel
        The run's forward model (its channels and species).
    species : str
        The species (the others absent).
    netd_K : float or sequence
        NETD per channel [K] (one value for all).
    background_K : float
        Radiometric temperature of the background behind the plume [K].
    gas_K, ambient_K : float
        Gas temperature at the plume centre and ambient temperature [K].
    sigma_m : float
        Plume depth along the line of sight [m] (the thin-limit signal per
        column hardly depends on it).

    Returns
    -------
    float
        NEC [kg/m2]; inf when the scene has no contrast (gas at the
        background's temperature).
    """
    if species not in model.species:
        raise ValueError(f"species {species!r} is not in the model ({model.species})")
    x = np.zeros(len(model.species))
    x[model.species.index(species)] = _PROBE_FRACTION
    signal = model.band_radiance(x, gas_K, sigma_m, ambient_K, background_K) - model.band_radiance(
        np.zeros_like(x), gas_K, sigma_m, ambient_K, background_K
    )
    col = float(np.asarray(model.column_density(x, gas_K, sigma_m, ambient_K)[species]))
    netd = np.broadcast_to(np.asarray(netd_K, dtype=float), (len(model.channels),))
    noise = np.array(
        [
            netd[c] * float(ch.band_radiance_derivative(background_K))
            for c, ch in enumerate(model.channels)
        ]
    )
    snr_per_column = np.abs(np.asarray(signal, float).reshape(-1)) / col / noise
    s = float(np.max(snr_per_column))
    return 1.0 / s if s > 0 else math.inf


def min_detectable_column(
    background_K: np.ndarray,
    model,
    species: str,
    netd_K,
    gas_K: float,
    ambient_K: float,
    confidence: float = CONFIDENCE,
    detection_sigma: float = DETECTION_SIGMA,
) -> np.ndarray:
    """Per pixel, the column density [kg/m2] a pixel must hold to be seen in a
    fraction ``confidence`` of the frames: ``(k + z) NEC(T_bg)``, with ``NEC``
    (:func:`noise_equivalent_column`) at that pixel's background radiometric
    temperature.

    Parameters
    ----------
    background_K : array (H, W)
        The background's radiometric temperature [K] per pixel (finite).
    model : qogi.physics.forward.ForwardModel
        The forward model (its channels and species).
    species : str
    netd_K : float or sequence
        NETD per channel [K].
    gas_K, ambient_K : float
        Gas and ambient temperature [K].
    confidence : float
        Fraction of frames (one-sided normal quantile z).
    detection_sigma : float
        The per-pixel threshold k in noise units.

    Returns
    -------
    array (H, W)
        Minimum-detectable column [kg/m2]; inf where the background has no
        contrast with the gas.
    """
    bg = np.asarray(background_K, float)
    z = NormalDist().inv_cdf(confidence)
    # 1/NEC (the signal per column and noise) varies smoothly, near linearly,
    # with the background's temperature: evaluated on a grid of it (0.25 K
    # steps at most, 64 points at most) and interpolated.
    lo, hi = float(bg.min()), float(bg.max())
    n = int(min(64, max(2, math.ceil((hi - lo) / 0.25) + 1)))
    grid = np.linspace(lo, hi, n) if hi > lo else np.array([lo])
    nec = np.array(
        [noise_equivalent_column(model, species, netd_K, t, gas_K, ambient_K) for t in grid]
    )
    inv = np.where(np.isfinite(nec), 1.0 / nec, 0.0)  # interpolate the signal, not its inverse
    s = np.interp(bg, grid, inv) if grid.size > 1 else np.full(bg.shape, inv[0])
    with np.errstate(divide="ignore"):
        return np.where(s > 0, (detection_sigma + z) / s, np.inf)


def median_background_K(
    recording, frames: Optional[range] = None, max_frames: int = 50, percentile: float = 50.0
):
    """The per-pixel temporal median (or another ``percentile``) [K] of the
    first channel's radiometric temperature over up to ``max_frames`` frames
    spread over ``frames`` (default: the whole recording). Where the gas comes
    and goes, the gas-free background; a low percentile where the gas is
    warmer than the background (emission), a high one where it is colder,
    keeps a plume that is there in most frames out of it. Non-finite pixels
    (dead, saturated) are filled with the median of the rest."""
    frames = range(recording.n_frames) if frames is None else frames
    n = len(frames)
    pick = np.unique(np.linspace(0, n - 1, min(n, max(1, int(max_frames)))).astype(int))
    # The frames as stored (a dead pixel's zero radiance has no temperature):
    # the percentile of the valid values, then one conversion; radiance and
    # temperature rise together, so the order is the same.
    stack = np.stack([recording.frame(frames[int(i)])[0] for i in pick]).astype(float)
    stack[~(np.isfinite(stack) & (stack > 0))] = np.nan
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN pixels: filled below
        level = np.nanpercentile(stack, percentile, axis=0)
    good = np.isfinite(level)
    bg = np.full(level.shape, np.nan)
    if recording.quantity == "radiance":
        bg[good] = band_table(recording.channels[0]).temperature(level[good])
    else:
        bg[good] = level[good]
    if good.any() and not good.all():
        bg[~good] = np.median(bg[good])
    return bg


def detection_limit_kg_s(
    nec_kg_m2: float,
    velocity_m_s: float,
    width_m: float,
    confidence: float = CONFIDENCE,
    detection_sigma: float = DETECTION_SIGMA,
) -> float:
    """The smallest detectable rate [kg/s] through a surface (module
    docstring): ``(k + z) NEC v w``.

    Parameters
    ----------
    nec_kg_m2 : float
        Noise-equivalent column [kg/m2] (:func:`noise_equivalent_column`).
    velocity_m_s : float
        Gas speed normal to the surface [m/s] (its magnitude is used).
    width_m : float
        Effective width of the plume along the surface [m] (``sum c dl / c_peak``).
    confidence : float
        Probability of detection in a frame at the limit, in (0.5, 1).
    detection_sigma : float
        The per-pixel detection threshold k in noise units.
    """
    if not 0.5 < confidence < 1:
        raise ValueError(f"confidence must be within (0.5, 1); got {confidence}")
    z = NormalDist().inv_cdf(confidence)
    return (detection_sigma + z) * nec_kg_m2 * abs(velocity_m_s) * width_m


def frame_widths(columns: np.ndarray, dl_m: np.ndarray) -> np.ndarray:
    """Per frame, the plume's effective width ``sum c dl / max c`` [m] along a
    surface (frames x samples); NaN for frames without gas."""
    c = np.where(np.isfinite(columns), np.clip(columns, 0, None), 0.0)
    peak = c.max(axis=1) if c.size else np.zeros(len(c))
    out = np.full(len(c), np.nan)
    seen = peak > 0
    out[seen] = (c[seen] * np.asarray(dl_m)[None, :]).sum(axis=1) / peak[seen]
    return out


def effective_width(columns: np.ndarray, dl_m: np.ndarray) -> Optional[float]:
    """Median over frames of the plume's effective width ``sum c dl / max c``
    [m] along a surface (frames x samples; frames without gas skipped); None
    when no frame has gas."""
    return _median_width(frame_widths(columns, dl_m))


def _median_width(widths: np.ndarray) -> Optional[float]:
    w = np.asarray(widths, float)
    w = w[np.isfinite(w)]
    return float(np.median(w)) if w.size else None


def velocity_sums(columns: np.ndarray, vn_m_s: np.ndarray) -> tuple:
    """What :func:`normal_velocity` needs, summable over blocks of frames:
    ``(sum c |v_n|, sum c, per-frame median |v_n|)`` (frames x samples
    inputs; NaN columns count as no gas)."""
    c = np.where(np.isfinite(columns), np.clip(columns, 0, None), 0.0)
    v = np.abs(np.asarray(vn_m_s, float))
    v = np.where(np.isfinite(v), v, 0.0)
    med = np.median(v, axis=1) if v.size else np.zeros(len(v))
    return float((c * v).sum()), float(c.sum()), med


def normal_velocity(columns: np.ndarray, vn_m_s: np.ndarray) -> float:
    """The measured gas speed normal to a surface [m/s]: the mean of ``|v_n|``
    weighted by the column (frames x samples; NaN columns ignored); the
    median over frames of each frame's median ``|v_n|`` where no gas was seen."""
    return velocity_from_sums(*velocity_sums(columns, vn_m_s))


def velocity_from_sums(cv: float, c: float, frame_medians: np.ndarray) -> float:
    if c > 0:
        return float(cv / c)
    m = np.asarray(frame_medians, float)
    return float(np.median(m)) if m.size else 0.0


def zeng_morris_g_h(delta_T_K, distance_m):
    """Zeng and Morris's detection limit of a FLIR GF320 with its standard
    lens [g/h]: ``18.41 |dT|^-1.094 d^2`` for a temperature contrast dT [K]
    between gas and background and a distance d [m] (Y. Zeng, J. Morris,
    Detection limits of optical gas imagers as a function of temperature
    differential and distance, J. Air Waste Manag. Assoc. 69 (2019) 351-361)."""
    dT = np.abs(np.asarray(delta_T_K, dtype=float))
    d = np.asarray(distance_m, dtype=float)
    return 18.41 * dT**-1.094 * d**2


def surface_detection_limit(
    model,
    species: str,
    netd_K,
    background_K: float,
    gas_K: float,
    ambient_K: float,
    columns: np.ndarray,
    vn_m_s: np.ndarray,
    dl_m: np.ndarray,
    mean_snr: Optional[np.ndarray] = None,
    confidence: float = CONFIDENCE,
):
    """The detection limit of one surface and species [kg/h] (None when the
    scene has no contrast) and what it came from, a dict for the result JSON:
    noise-equivalent column, measured normal velocity and effective width
    (and where they came from), confidence and k.

    ``columns`` and ``vn_m_s`` are frames x samples, ``dl_m`` the samples'
    lengths [m]; ``mean_snr`` (optional) the time-averaged contrast along the
    surface in units of its own noise (the per-frame noise / sqrt(frames)):
    where no single frame saw gas, the average over frames may still show
    the plume, and its width then replaces the surface length. The pipeline,
    which streams frames in blocks, passes the same quantities summed over
    blocks to :func:`detection_limit_from_sums`."""
    return detection_limit_from_sums(
        model,
        species,
        netd_K,
        background_K,
        gas_K,
        ambient_K,
        normal_velocity(columns, vn_m_s),
        frame_widths(columns, dl_m),
        dl_m,
        mean_snr,
        confidence,
    )


def detection_limit_from_sums(
    model,
    species: str,
    netd_K,
    background_K: float,
    gas_K: float,
    ambient_K: float,
    velocity_m_s: float,
    widths_m: np.ndarray,
    dl_m: np.ndarray,
    mean_snr: Optional[np.ndarray] = None,
    confidence: float = CONFIDENCE,
):
    """:func:`surface_detection_limit` from the measured normal speed [m/s]
    (:func:`normal_velocity`) and the per-frame effective widths [m]
    (:func:`frame_widths`, NaN without gas)."""
    nec = noise_equivalent_column(model, species, netd_K, background_K, gas_K, ambient_K)
    v = float(velocity_m_s)
    # The time-averaged contrast shows the plume's whole width (its noise is
    # sqrt(frames) lower); a frame's columns only the part above the per-pixel
    # threshold, too narrow near the limit.
    # Its peak must stand out of the noise of all the surface's samples, not
    # of one: the largest of N noise samples exceeds k noise far more often
    # than one does (a blank's noise once gave a one-pixel "plume" and a
    # limit 20x below what the scene lets anyone detect).
    w, width_from = None, ""
    if mean_snr is not None:
        w = _mean_profile_width(
            mean_snr, dl_m, detection_sigma=significant_peak(len(mean_snr), confidence)
        )
        width_from = "time-averaged contrast"
    else:
        # Without the time average, the frames' thresholded columns.
        w = _median_width(widths_m)
        width_from = "columns of the frames"
    if w is None:
        w, width_from = float(np.sum(dl_m)), "surface length (no gas seen: an upper bound)"
    limit = detection_limit_kg_s(nec, v, w, confidence) * 3600.0
    info = {
        "noise_equivalent_column_kg_m2": _json_float(nec),
        "velocity_m_s": v,
        "width_m": w,
        "width_from": width_from,
        "background_temperature_K": float(background_K),
        "gas_temperature_K": float(gas_K),
        "confidence": float(confidence),
        "detection_sigma": DETECTION_SIGMA,
    }
    return (limit if math.isfinite(limit) and limit > 0 else None), info


def significant_peak(
    n_samples: int, confidence: float = CONFIDENCE, detection_sigma: float = DETECTION_SIGMA
) -> float:
    """The peak (in noise units) a profile of ``n_samples`` independent
    samples of pure noise exceeds with probability ``1 - confidence``: the
    one-sided normal quantile at ``confidence ** (1 / n)`` (Sidak's
    correction for looking at every sample), at least ``detection_sigma``.
    200 samples at 95 %: 3.48."""
    n = max(1, int(n_samples))
    if not 0.5 < confidence < 1:
        raise ValueError(f"confidence must be within (0.5, 1); got {confidence}")
    return max(float(detection_sigma), NormalDist().inv_cdf(confidence ** (1.0 / n)))


def _mean_profile_width(
    snr: np.ndarray, dl_m: np.ndarray, detection_sigma: float, cut: float = 0.2
) -> Optional[float]:
    """Effective width [m] (sum / peak over the part above ``cut`` x its peak)
    of a time-averaged contrast profile in noise units, when its peak is
    significant (>= ``detection_sigma``); else None."""
    p = np.where(np.isfinite(snr), np.asarray(snr, float), 0.0)
    top = float(p.max()) if p.size else 0.0
    if not top >= detection_sigma:
        return None
    keep = p > cut * top
    return float((p[keep] * np.asarray(dl_m)[keep]).sum() / top)


def _json_float(x: float) -> Optional[float]:
    return float(x) if math.isfinite(x) else None
