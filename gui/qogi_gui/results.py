"""Reading a ``qogi.Result`` for display: tables, series, maps, vectors.

Only the attributes of the pipeline contract (docs/pipeline_api.md) are used.
Rates are kg/s inside the result; everything here is in kg/h, the unit a
technician reads, unless a name says otherwise.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Sequence, Tuple

import numpy as np

__all__ = [
    "RateRow",
    "rate_rows",
    "uncertainty_terms",
    "warning_lines",
    "rate_series",
    "finite_segments",
    "pixel_status_rows",
    "standard_conditions_text",
    "frame_maps",
    "map_frame_keys",
    "full_frame_maps",
    "vector_field",
    "overlay_scale",
    "arrow_segments",
]

KG_S_TO_KG_H = 3600.0
STATUS_ORDER = ("converged", "at bound", "below detection", "failed", "masked")


@dataclass
class RateRow:
    """One surface and species: the numbers a person reads off the result."""

    surface: str
    species: str
    mean_kg_h: float
    ci90_kg_h: Tuple[float, float]
    mean_g_h: float
    mean_slpm: float
    truth_kg_h: Optional[float]
    n_frames: int
    n_frames_valid: int
    pixels_median: float
    dominant_uncertainty: str
    #: qogi.pipeline.detection's limit [kg/h] (None: not computed) and whether the mean
    #: is above it (None: no limit).
    detection_limit_kg_h: Optional[float] = None
    detected: Optional[bool] = None
    #: What "not detected, < X" says (qogi.SpeciesRate.upper_limit_kg_h; None when detected).
    upper_limit_kg_h: Optional[float] = None
    #: The uncertainty budget: 1-sigma contribution [kg/h] per term
    #: (temporal, velocity, column density, line shape, background ...).
    uncertainty_terms_kg_h: Dict[str, float] = field(default_factory=dict)

    @property
    def detection_text(self) -> str:
        """``"0.0011"``, ``"< 0.0011 (not detected)"`` or ``"-"`` (kg/h)."""
        if self.detection_limit_kg_h is None or not math.isfinite(self.detection_limit_kg_h):
            return "-"
        if self.detected is False:
            up = self.upper_limit_kg_h
            bound = up if up is not None and math.isfinite(up) else self.detection_limit_kg_h
            return f"< {bound:.3g} (not detected)"
        return f"{self.detection_limit_kg_h:.3g}"

    @property
    def error_pct(self) -> Optional[float]:
        """(mean - truth) / truth in percent, when the truth is known and non-zero."""
        if self.truth_kg_h is None or self.truth_kg_h == 0 or not math.isfinite(self.mean_kg_h):
            return None
        return 100.0 * (self.mean_kg_h - self.truth_kg_h) / self.truth_kg_h

    @property
    def truth_inside_ci(self) -> Optional[bool]:
        if self.truth_kg_h is None:
            return None
        lo, hi = self.ci90_kg_h
        return bool(lo <= self.truth_kg_h <= hi)


def _f(x) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def rate_rows(result) -> List[RateRow]:
    """One :class:`RateRow` per surface and species, in the result's order."""
    rows = []
    for sr in result.surfaces:
        name = sr.surface.name or "surface"
        for sp, r in sr.species.items():
            rate = np.asarray(r.rate_kg_s, dtype=float)
            pix = np.asarray(getattr(r, "pixels_used", []), dtype=float)
            lo, hi = (tuple(r.ci90_kg_h) + (math.nan, math.nan))[:2]
            truth = getattr(r, "truth_kg_h", None)
            rows.append(
                RateRow(
                    surface=name,
                    species=sp,
                    mean_kg_h=_f(r.mean_kg_h),
                    ci90_kg_h=(_f(lo), _f(hi)),
                    mean_g_h=_f(getattr(r, "mean_g_h", math.nan)),
                    mean_slpm=_f(getattr(r, "mean_slpm", math.nan)),
                    truth_kg_h=None if truth is None else _f(truth),
                    n_frames=int(getattr(r, "n_frames", rate.size)),
                    n_frames_valid=int(np.count_nonzero(np.isfinite(rate))),
                    pixels_median=float(np.median(pix)) if pix.size else math.nan,
                    dominant_uncertainty=str(getattr(r, "dominant_uncertainty", "")),
                    detection_limit_kg_h=getattr(r, "detection_limit_kg_h", None),
                    detected=getattr(r, "detected", None),
                    upper_limit_kg_h=getattr(r, "upper_limit_kg_h", None),
                    uncertainty_terms_kg_h={
                        str(k): _f(v)
                        for k, v in (getattr(r, "uncertainty_terms_kg_h", None) or {}).items()
                    },
                )
            )
    return rows


def uncertainty_terms(rows: Sequence[RateRow]) -> List[str]:
    """The budget's term names over ``rows``, in the order they first appear."""
    return list(dict.fromkeys(k for r in rows for k in r.uncertainty_terms_kg_h))


def warning_lines(result) -> List[str]:
    """The result's warnings (``Result.warnings``), one line each:
    ``[code surface/species] message``."""
    return [str(w) for w in getattr(result, "warnings", None) or ()]


def rate_series(result) -> List[dict]:
    """Per surface and species: ``surface``, ``species``, ``time_s``,
    ``rate_kg_h`` (NaN where a frame could not be quantified), ``mean_kg_h``,
    ``ci90_kg_h``, ``truth_kg_h``."""
    out = []
    for sr in result.surfaces:
        for sp, r in sr.species.items():
            out.append(
                {
                    "surface": sr.surface.name or "surface",
                    "species": sp,
                    "time_s": np.asarray(r.time_s, dtype=float),
                    "rate_kg_h": np.asarray(r.rate_kg_s, dtype=float) * KG_S_TO_KG_H,
                    "mean_kg_h": _f(r.mean_kg_h),
                    "ci90_kg_h": tuple(_f(v) for v in r.ci90_kg_h),
                    "truth_kg_h": getattr(r, "truth_kg_h", None),
                }
            )
    return out


def standard_conditions_text(result) -> str:
    """The standard conditions the result's SLPM refer to, for people
    ("293.15 K, 101325 Pa"); "" when the result does not say."""
    sc = getattr(result, "standard_conditions", None)
    if isinstance(sc, dict):
        t, p = sc.get("temperature_K"), sc.get("pressure_Pa")
        if t is not None and p is not None:
            return f"{float(t):g} K, {float(p):g} Pa"
        return ", ".join(f"{k} {v}" for k, v in sc.items())
    return str(sc) if sc else ""


def finite_segments(x: Sequence[float], y: Sequence[float]) -> List[Tuple[np.ndarray, np.ndarray]]:
    """Split a series at non-finite values into runs of finite points, so a
    plot shows gaps where frames could not be quantified instead of bridging them."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    ok = np.isfinite(x) & np.isfinite(y)
    segs = []
    i, n = 0, len(ok)
    while i < n:
        if not ok[i]:
            i += 1
            continue
        j = i
        while j < n and ok[j]:
            j += 1
        segs.append((x[i:j], y[i:j]))
        i = j
    return segs


def pixel_status_rows(result) -> List[Tuple[str, int, float]]:
    """(status, count, percent of all counted pixels), known statuses first;
    statuses are named in words ("at_bound" reads "at bound")."""
    status = {}
    for k, v in dict(getattr(result, "pixel_status", {}) or {}).items():
        name = str(k).replace("_", " ")
        status[name] = status.get(name, 0) + int(v)
    total = sum(status.values())
    names = [s for s in STATUS_ORDER if s in status] + sorted(set(status) - set(STATUS_ORDER))
    return [
        (s, int(status[s]), 100.0 * int(status[s]) / total if total else math.nan) for s in names
    ]


def map_frame_keys(result) -> Dict[int, int]:
    """Recording frame index -> key of ``result.maps`` for every frame whose
    per-pixel maps the result kept (``result.map_frames``).

    docs/pipeline_api.md keys ``result.maps(frame)`` by the recording's frame
    index; the pipeline at present keys them by the position within the
    analysed frames (``config.frames``). The two differ only when the analysis
    starts after frame 0, and then unambiguously: positional keys include 0
    (the first analysed frame always keeps its maps), which is before the
    start. Both are read right here.
    """
    keys = [int(k) for k in (getattr(result, "map_frames", None) or [])]
    frames = getattr(getattr(result, "config", None), "frames", None)
    start = int(frames[0]) if frames else 0
    offset = start if keys and start > 0 and min(keys) < start else 0
    return {k + offset: k for k in keys}


def frame_maps(result, frame: int, shape: Optional[Tuple[int, int]] = None) -> Optional[dict]:
    """The result's maps of recording frame ``frame`` (see
    :func:`map_frame_keys`), or None when the result holds no maps for that
    frame (run without keep_maps, or a frame outside the analysed range).

    With ``shape`` (H, W) of the recording, maps that cover only part of the
    frame (an ``origin`` (x0, y0) and smaller arrays) are placed into
    full-frame arrays: NaN (status -1) outside the analysed part.
    """
    if result is None or not hasattr(result, "maps"):
        return None
    key = map_frame_keys(result).get(int(frame))
    if key is None:
        return None
    try:
        maps = result.maps(key)
    except (ValueError, IndexError, KeyError, LookupError, RuntimeError):
        return None
    if shape is None or not maps:
        return maps
    return full_frame_maps(maps, shape)


def _embed(a, origin: Tuple[int, int], shape: Tuple[int, int], fill) -> np.ndarray:
    a = np.asarray(a)
    if a.shape == tuple(shape):
        return a
    x0, y0 = int(round(origin[0])), int(round(origin[1]))
    out = np.full(shape, fill, dtype=np.float32 if isinstance(fill, float) else np.int16)
    h, w = a.shape
    ys, xs = slice(max(0, y0), min(shape[0], y0 + h)), slice(max(0, x0), min(shape[1], x0 + w))
    out[ys, xs] = a[ys.start - y0 : ys.stop - y0, xs.start - x0 : xs.stop - x0]
    return out


def full_frame_maps(maps: dict, shape: Tuple[int, int]) -> dict:
    """``maps`` with every array the size of the frame (see :func:`frame_maps`)."""
    origin = tuple(maps.get("origin", (0, 0)))
    out = dict(maps)
    if "column_density_kg_m2" in maps:
        out["column_density_kg_m2"] = {
            sp: _embed(c, origin, shape, np.nan) for sp, c in maps["column_density_kg_m2"].items()
        }
    if "velocity_px_per_frame" in maps:
        u, v = maps["velocity_px_per_frame"]
        out["velocity_px_per_frame"] = (
            _embed(u, origin, shape, np.nan),
            _embed(v, origin, shape, np.nan),
        )
    if "status" in maps:
        st = np.asarray(maps["status"])
        out["status"] = _embed(st, origin, shape, -1) if np.issubdtype(st.dtype, np.number) else st
    if "velocity_region" in maps:  # x0, y0, x1, y1 in the maps' pixels: now the frame's
        x0, y0, x1, y1 = maps["velocity_region"]
        ox, oy = int(round(origin[0])), int(round(origin[1]))
        out["velocity_region"] = (x0 + ox, y0 + oy, x1 + ox, y1 + oy)
    out["origin"] = (0, 0)
    return out


def overlay_scale(
    result, species: str, frames: Sequence[int], shape: Optional[Tuple[int, int]] = None
) -> float:
    """A column-density colour-scale top [kg/m2] for ``species``: the 99.5th
    percentile of the positive values over a few frames' maps (fixed for the
    whole playback so the colours mean the same in every frame)."""
    vals = []
    for f in frames:
        m = frame_maps(result, int(f), shape)
        if not m:
            continue
        col = m.get("column_density_kg_m2", {}).get(species)
        if col is None:
            continue
        a = np.asarray(col, dtype=float)
        a = a[np.isfinite(a) & (a > 0)]
        if a.size:
            vals.append(a)
    if not vals:
        return 0.0
    return float(np.percentile(np.concatenate(vals), 99.5))


def vector_field(
    u: np.ndarray,
    v: np.ndarray,
    weight: Optional[np.ndarray] = None,
    spacing: int = 12,
    min_weight: float = 0.0,
    target_px: Optional[float] = None,
) -> Tuple[np.ndarray, np.ndarray, float]:
    """Arrows for a velocity map on a regular grid.

    Parameters
    ----------
    u, v : (H, W) px/frame
        Velocity (x right, y down).
    weight : (H, W), optional
        Arrows only where ``weight > min_weight`` (e.g. column density, so
        vectors show where the gas is).
    spacing : int, px
        Grid step.
    target_px : float, optional
        Length the 95th-percentile speed is drawn with (default ``0.9 * spacing``).

    Returns
    -------
    tails : (N, 2) float, px
    heads : (N, 2) float, px
    scale : float
        Drawn length per px/frame (arrow length = scale * speed).
    """
    u, v = np.asarray(u, dtype=float), np.asarray(v, dtype=float)
    h, w = u.shape
    ys, xs = np.mgrid[spacing // 2 : h : spacing, spacing // 2 : w : spacing]
    uu, vv = u[ys, xs], v[ys, xs]
    keep = np.isfinite(uu) & np.isfinite(vv)
    if weight is not None:
        ww = np.asarray(weight, dtype=float)[ys, xs]
        keep &= np.isfinite(ww) & (ww > min_weight)
    xs, ys, uu, vv = xs[keep], ys[keep], uu[keep], vv[keep]
    speed = np.hypot(uu, vv)
    if speed.size == 0 or not np.any(speed > 0):
        return np.zeros((0, 2)), np.zeros((0, 2)), 0.0
    ref = float(np.percentile(speed[speed > 0], 95))
    scale = (0.9 * spacing if target_px is None else float(target_px)) / ref
    tails = np.column_stack([xs, ys]).astype(float)
    heads = tails + scale * np.column_stack([uu, vv])
    return tails, heads, scale


def arrow_segments(
    tails: np.ndarray,
    heads: np.ndarray,
    head_frac: float = 0.3,
    head_angle_deg: float = 25.0,
    min_head: float = 0.0,
) -> Tuple[np.ndarray, np.ndarray]:
    """Arrows as line segments for a plot: shaft plus two head strokes each.

    Returns x and y arrays laid out as consecutive (start, end) pairs (3 pairs
    per arrow), for a segment line series. Zero-length arrows are skipped.
    """
    tails = np.asarray(tails, dtype=float).reshape(-1, 2)
    heads = np.asarray(heads, dtype=float).reshape(-1, 2)
    d = heads - tails
    length = np.hypot(d[:, 0], d[:, 1])
    keep = length > 0
    tails, heads, d, length = tails[keep], heads[keep], d[keep], length[keep]
    if len(tails) == 0:
        return np.zeros(0), np.zeros(0)
    back = -d / length[:, None]
    hl = np.maximum(head_frac * length, min_head)[:, None]
    a = np.radians(head_angle_deg)
    c, s = np.cos(a), np.sin(a)
    left = np.column_stack([c * back[:, 0] - s * back[:, 1], s * back[:, 0] + c * back[:, 1]])
    right = np.column_stack([c * back[:, 0] + s * back[:, 1], -s * back[:, 0] + c * back[:, 1]])
    pts = np.stack([tails, heads, heads, heads + hl * left, heads, heads + hl * right], axis=1)
    pts = pts.reshape(-1, 2)
    return pts[:, 0], pts[:, 1]
