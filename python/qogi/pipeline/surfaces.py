"""Control surfaces in the image: lines and polylines across which flux is counted.

Pixel coordinates: x to the right, y down, origin at the top-left pixel centre.
Sign convention: flux through a surface is positive along its **left-hand
normal** when walking from its first point to its last in the image as
displayed (x right, y down). A horizontal line drawn left to right therefore
counts upward flow (towards smaller y) as positive. For a segment direction
``d = (dx, dy)`` that normal is ``(dy, -dx) / |d|``.
"""

from __future__ import annotations

import dataclasses
from typing import List, Optional, Sequence, Tuple

import numpy as np

__all__ = ["Surface", "Region", "auto_surfaces", "detect_source", "plume_image", "truth_surfaces"]

Point = Tuple[float, float]


@dataclasses.dataclass
class Surface:
    """A control surface: a line (2 points) or polyline (>= 2 points) in pixels.

    Parameters
    ----------
    points : sequence of (x, y)
        Vertices in pixel coordinates (floats allowed).
    name : str
        Shown in results and plots (default ``S1``, ``S2``... by position).
    """

    points: List[Point]
    name: str = ""

    def __post_init__(self):
        pts = np.asarray(self.points, dtype=float)
        if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2:
            raise ValueError(f"a surface needs at least 2 points (x, y); got {self.points!r}")
        if not np.all(np.isfinite(pts)):
            raise ValueError(f"surface points must be finite; got {self.points!r}")
        seg = np.diff(pts, axis=0)
        if np.any(np.hypot(seg[:, 0], seg[:, 1]) == 0):
            raise ValueError(
                f"surface {self.name!r} has two equal consecutive points; remove the duplicate"
            )
        self.points = [(float(x), float(y)) for x, y in pts]

    @property
    def length_px(self) -> float:
        d = np.diff(np.asarray(self.points), axis=0)
        return float(np.hypot(d[:, 0], d[:, 1]).sum())

    def reversed(self) -> Surface:
        return Surface(list(reversed(self.points)), self.name)

    def oriented_away_from(self, source: Point) -> Surface:
        """This surface with its points reversed if needed, so that flow away
        from ``source`` (x, y) counts as positive."""
        xy, n, w = self.samples(step_px=1.0)
        away = xy - np.asarray(source, dtype=float)
        if float(np.sum(np.einsum("ij,ij->i", away, n) * w)) < 0:
            return self.reversed()
        return self

    def samples(self, step_px: float = 0.5):
        """Points along the surface with their unit normals and lengths.

        Returns ``(xy (N, 2), normal (N, 2), length_px (N,))``: midpoints of
        sub-segments of at most ``step_px``, the left-hand unit normal of their
        segment, and their lengths in pixels (summing to the surface length).
        """
        pts = np.asarray(self.points, dtype=float)
        xy, nrm, ln = [], [], []
        for a, b in zip(pts[:-1], pts[1:]):
            d = b - a
            L = float(np.hypot(*d))
            k = max(1, int(np.ceil(L / step_px)))
            t = (np.arange(k) + 0.5) / k
            xy.append(a + t[:, None] * d)
            nrm.append(np.repeat([[d[1] / L, -d[0] / L]], k, axis=0))
            ln.append(np.full(k, L / k))
        return np.concatenate(xy), np.concatenate(nrm), np.concatenate(ln)

    def bounds(self, margin: float = 0.0) -> Tuple[float, float, float, float]:
        p = np.asarray(self.points)
        return (
            float(p[:, 0].min() - margin),
            float(p[:, 1].min() - margin),
            float(p[:, 0].max() + margin),
            float(p[:, 1].max() + margin),
        )

    def to_dict(self) -> dict:
        return {"name": self.name, "points": [list(p) for p in self.points]}

    @classmethod
    def from_dict(cls, d: dict) -> Surface:
        return cls([tuple(p) for p in d["points"]], d.get("name", ""))

    @classmethod
    def parse(cls, text: str, name: str = "") -> Surface:
        """From ``"x0,y0,x1,y1[,x2,y2...]"`` (the CLI's ``--surface``)."""
        try:
            v = [float(s) for s in text.replace(";", ",").split(",") if s.strip()]
        except ValueError:
            raise ValueError(f"surface {text!r}: expected numbers x0,y0,x1,y1[,...]") from None
        if len(v) < 4 or len(v) % 2:
            raise ValueError(
                f"surface {text!r}: expected an even number (>= 4) of coordinates "
                "x0,y0,x1,y1[,x2,y2...]"
            )
        return cls(list(zip(v[0::2], v[1::2])), name)


@dataclasses.dataclass
class Region:
    """A pixel rectangle ``[x0, x1) x [y0, y1)`` (e.g. a gas-free background patch)."""

    x0: int
    y0: int
    x1: int
    y1: int

    def __post_init__(self):
        for f in ("x0", "y0", "x1", "y1"):
            setattr(self, f, int(getattr(self, f)))
        if self.x1 <= self.x0 or self.y1 <= self.y0:
            raise ValueError(f"region {self} is empty: need x0 < x1 and y0 < y1")

    def clip(self, width: int, height: int) -> Region:
        r = Region(max(0, self.x0), max(0, self.y0), min(width, self.x1), min(height, self.y1))
        return r

    def slices(self) -> Tuple[slice, slice]:
        return slice(self.y0, self.y1), slice(self.x0, self.x1)

    @classmethod
    def parse(cls, text: str) -> Region:
        v = [int(float(s)) for s in text.split(",")]
        if len(v) != 4:
            raise ValueError(f"region {text!r}: expected x0,y0,x1,y1")
        return cls(*v)


def _smooth_background(img: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Robust quadratic surface through a 2-D image: least squares, then
    refitted without the pixels more than 2.5 sigma above or below it (a
    plume), a few times."""
    h, w = img.shape
    y, x = np.mgrid[0:h, 0:w]
    x = (x.ravel() - 0.5 * w) / w
    y = (y.ravel() - 0.5 * h) / h
    a = np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=1)
    v = img.ravel()
    keep = np.ones(v.size, bool)
    for _ in range(iterations):
        coef, *_ = np.linalg.lstsq(a[keep], v[keep], rcond=None)
        r = v - a @ coef
        sd = 1.4826 * np.median(np.abs(r[keep] - np.median(r[keep])))
        if not sd > 0:
            break
        keep = np.abs(r) < 2.5 * sd
    return (a @ coef).reshape(h, w)


def plume_image(recording, max_frames: int = 50) -> np.ndarray:
    """A plume-detection image for :func:`auto_surfaces` from a recording's
    first ``max_frames`` frames, in units of the camera noise, averaged over
    the channels: the mean band radiance's departure from a smooth background
    (a robust quadratic surface: a sky's elevation gradient, a plate's
    vignetting) plus each pixel's temporal standard deviation (a turbulent
    plume fluctuates, a static background does not), each divided by the
    channel's median temporal standard deviation (its noise)."""
    n = min(int(recording.n_frames), int(max_frames))
    if n < 2:
        raise ValueError("plume detection needs at least 2 frames")
    return _plume_image(np.asarray(recording.frames(0, n, quantity="radiance"), dtype=np.float64))


def _plume_image(frames: np.ndarray) -> np.ndarray:
    """:func:`plume_image` of a (T, C, H, W) radiance stack."""
    mean = frames.mean(axis=0)  # (C, H, W)
    sd = frames.std(axis=0)
    out = np.zeros(mean.shape[1:])
    for c in range(mean.shape[0]):
        noise = float(np.median(sd[c]))
        noise = noise if noise > 0 else 1.0
        out += (np.abs(mean[c] - _smooth_background(mean[c])) + sd[c]) / noise
    return out / mean.shape[0]


def _plume_axis(image: np.ndarray, threshold: float):
    """Mask pixels (N, 2) as (x, y), their weights, the weighted centre and
    the principal axis of the plume in a detection image."""
    img = np.abs(np.asarray(image, dtype=float))
    if img.ndim != 2:
        raise ValueError(f"plume detection needs a 2-D image; got shape {img.shape}")
    ref = np.percentile(img, 99.5)
    if not ref > 0:
        raise ValueError("no plume detected: the image is zero everywhere")
    mask = img > threshold * ref
    ys, xs = np.nonzero(mask)
    if len(xs) < 10:
        raise ValueError("no plume detected: fewer than 10 pixels above the threshold")
    w = img[ys, xs]
    pts = np.stack([xs, ys], axis=1).astype(float)
    c = np.average(pts, axis=0, weights=w)
    cov = np.cov((pts - c).T, aweights=w)
    _evals, evecs = np.linalg.eigh(cov)
    return pts, w, c, evecs[:, -1]


def detect_source(image: np.ndarray, threshold: float = 0.1) -> Point:
    """The source of the plume in a detection image (:func:`plume_image`),
    at the mask's mean position at one end of its principal axis.

    Three cues vote for the end (docs/pipeline_api.md, "Source detection"):

    * **where the gas leaves the frame**: an end whose mask runs into the
      image border while the other does not is where the plume leaves
      (a source outside the view is not detected: give it);
    * **the column's gradient along the plume**: the time-averaged signal
      falls downstream (a rising plume's centreline column ~ z^(-2/3), a
      wind-bent plume's ~ 1 / width), so the source end is the stronger;
    * **the width**: plumes widen downstream (the stack of a rising plume,
      the upwind end of one bent by wind), so the source end is narrower.

    The border cue decides when it is one-sided; otherwise the signal
    (when the ends differ by more than 20 %) and then the width. Raises
    ValueError when no plume stands out."""
    img = np.abs(np.asarray(image, dtype=float))
    pts, w, c, axis = _plume_axis(img, threshold)

    def ends_of(a):
        along = (pts - c) @ a
        lo, hi = np.percentile(along, [2.0, 98.0])
        span = max(hi - lo, 1.0)
        ends = (along <= lo + 0.15 * span, along >= hi - 0.15 * span)
        sig = [float(np.median(w[e])) if e.any() else 0.0 for e in ends]
        return along, lo, hi, span, ends, max(sig) / max(min(sig), 1e-300)

    # The plume's axis: the mask's principal axis, unless the signal falls
    # more clearly across it (a plume that fills a small view's width is as
    # wide as it is long; along its flow the column falls, across it it is
    # symmetric).
    perp = np.array([axis[1], -axis[0]])
    first_try, second_try = ends_of(axis), ends_of(perp)
    if second_try[5] > 1.2 and second_try[5] > 1.5 * first_try[5]:
        axis, perp = perp, -axis
        first_try = second_try
    along, lo, hi, span, ends, _ = first_try
    across = (pts - c) @ perp
    h, wd = img.shape
    border = [
        bool(
            np.any(
                (pts[e, 0] <= 1) | (pts[e, 0] >= wd - 2) | (pts[e, 1] <= 1) | (pts[e, 1] >= h - 2)
            )
        )
        for e in ends
    ]
    signal = [float(np.median(w[e])) for e in ends]
    width = [float(np.std(across[e])) for e in ends]
    if border[0] != border[1]:
        first = border[1]  # the end that does not leave the frame
    elif max(signal) > 1.2 * min(signal):
        first = signal[0] > signal[1]
    else:
        first = width[0] <= width[1]
    tip = along <= lo + 0.05 * span if first else along >= hi - 0.05 * span
    # The signal-weighted position there (the plume's axis, not the mask's
    # mean, where the mask fills a small view's width).
    x, y = np.average(pts[tip], axis=0, weights=w[tip] ** 2)
    return float(x), float(y)


def auto_surfaces(
    column_or_contrast: np.ndarray,
    distances_px: Sequence[float],
    source: Optional[Point] = None,
    threshold: float = 0.1,
    margin_px: float = 10.0,
    return_source: bool = False,
    warnings=None,
):
    """Detect the plume in a (time-averaged) column-density or contrast image
    and place straight surfaces across it at the given distances from the source.

    The plume mask is where the image exceeds ``threshold`` times its 99.5th
    percentile (:func:`plume_image` makes a suitable image from a recording).
    The plume direction is the principal axis of the mask. Without
    ``source``, the source is the mask's end along that axis where the plume
    is narrower (plumes widen downstream: the stack of a lab release, the
    upwind end of a plume bent by wind), at the mask's mean position across
    the axis there; the axis is oriented away from the source. Each surface is
    perpendicular to that axis, at ``distance`` along it, spanning the mask's
    width there plus the larger of ``margin_px`` and half that width on both
    sides (its background is taken just beyond its ends), oriented so that flow away
    from the source is positive.

    Each distance must be positive (downstream of the source) and keep the
    surface's centre inside the image: otherwise ValueError naming the usable
    distances. A surface whose ends reach beyond the image is shortened
    along itself to the image (it stays perpendicular to the axis) and, when
    ``warnings`` (a :class:`qogi.diagnostics.Diagnostics`) is given, a
    ``surface-clipped`` warning says how much was cut: the plume's part
    outside the image is not counted.

    Returns the list of surfaces, or ``(surfaces, (x, y) source)`` with
    ``return_source=True`` (e.g. for ``QuantifyConfig(source=...)``, which
    turns on the transport flux level of the default velocimetry).
    """
    img = np.abs(np.asarray(column_or_contrast, dtype=float))
    pts, _w, c, axis = _plume_axis(img, threshold)
    if source is None:
        source = detect_source(img, threshold)
    src = np.asarray(source, dtype=float)
    if np.dot(c - src, axis) < 0:
        axis = -axis
    perp = np.array([axis[1], -axis[0]])
    out = []
    h, wd = img.shape
    t_in, t_out = _span_in_image(src, axis, wd, h)
    for k, dist in enumerate(float(d) for d in distances_px):
        if not (np.isfinite(dist) and dist > 0):
            raise ValueError(
                f"distance {dist:g} px: surfaces are placed downstream of the source "
                f"(x={src[0]:.1f}, y={src[1]:.1f}) along the plume; give distances > 0 px"
            )
        if not t_in <= dist <= t_out:
            lo_d, hi_d = max(np.ceil(t_in), 1.0), np.floor(t_out)
            usable = (
                "the plume's axis does not cross the image downstream of the source"
                if hi_d < lo_d
                else f"the largest usable distance is {hi_d:.0f} px"
                if lo_d <= 1.0
                else f"usable distances are {lo_d:.0f} to {hi_d:.0f} px"
            )
            raise ValueError(
                f"distance {dist:g} px puts the surface's centre outside the {wd} x {h} "
                f"image (along the plume's axis from the source at x={src[0]:.1f}, "
                f"y={src[1]:.1f}); {usable}"
            )
        # Extent of the mask across the axis near this distance.
        along = (pts - src) @ axis
        near = np.abs(along - dist) < 3
        if near.any():
            across = (pts[near] - src) @ perp
            pad = max(margin_px, 0.5 * float(across.max() - across.min()))
            lo, hi = across.min() - pad, across.max() + pad
        else:
            lo, hi = -margin_px, margin_px
        mid = src + dist * axis
        c_lo, c_hi = _span_in_image(mid, perp, wd, h)
        cut_lo, cut_hi = max(lo, c_lo), min(hi, c_hi)
        if cut_hi - cut_lo < 1.0:
            raise ValueError(
                f"distance {dist:g} px: the plume's width there lies outside the {wd} x {h} "
                "image; choose a distance where the plume is inside the image"
            )
        # Onto the image's box: an end cut at its edge lands a rounding
        # error beyond it (-1e-14 px), which the run refuses.
        a, b = (np.clip(mid + t * perp, 0.0, [wd - 1, h - 1]) for t in (cut_lo, cut_hi))
        s = Surface([tuple(a), tuple(b)], name=f"A{k + 1} ({dist:g} px)")
        if warnings is not None and (cut_lo > lo or cut_hi < hi):
            warnings.add(
                "surface-clipped",
                f"surface {s.name} was cut to the image: {s.length_px:.1f} of "
                f"{hi - lo:.1f} px are inside it; gas crossing the part outside "
                "the image is not counted (choose a distance where the plume is "
                "inside the image)",
                surface=s.name,
                length_px=round(float(s.length_px), 2),
                wanted_px=round(float(hi - lo), 2),
            )
        out.append(s.oriented_away_from(tuple(src)))
    if return_source:
        return out, (float(src[0]), float(src[1]))
    return out


def _span_in_image(p: np.ndarray, d: np.ndarray, width: int, height: int) -> Tuple[float, float]:
    """The range (t0, t1) of t where ``p + t d`` lies in the image's pixel
    centres [0, width-1] x [0, height-1] (t0 > t1: the line misses it)."""
    t0, t1 = -np.inf, np.inf
    for x, dx, top in ((p[0], d[0], width - 1), (p[1], d[1], height - 1)):
        if abs(dx) < 1e-12:
            if not 0 <= x <= top:
                return np.inf, -np.inf
            continue
        a, b = (0 - x) / dx, (top - x) / dx
        t0, t1 = max(t0, min(a, b)), min(t1, max(a, b))
    return float(t0), float(t1)


def truth_surfaces(
    recording,
    heights_m: Optional[Sequence[float]] = None,
    max_height_m: Optional[float] = None,
    half_width_px: Optional[float] = None,
):
    """Horizontal control surfaces on a synthetic recording's truth planes.

    A recording written by ``qogi synth`` stores the image row of each
    horizontal control plane above the stack exit (``/truth`` datasets
    ``plane_height_m`` and ``plane_row``); this places a surface on each,
    centred on the exit, and returns the exit pixel for
    ``QuantifyConfig(source=...)``.

    Parameters
    ----------
    recording : qogi.Recording
        A synthetic recording with those truth datasets.
    heights_m : sequence of float, m, optional
        The planes to use (matched to the stored heights within 1 mm); default all.
    max_height_m : float, m, optional
        Only planes up to this height.
    half_width_px : float, px, optional
        Half the surface length; default a third of the image width, at most 50 px.

    Returns
    -------
    (list of Surface, (x, y) exit pixel)
    """
    truth = getattr(recording, "truth", None)
    if truth is None or "plane_row" not in truth.datasets or "plane_height_m" not in truth.datasets:
        raise ValueError(
            "truth_surfaces needs a synthetic recording with /truth plane_row and "
            "plane_height_m (written by qogi synth)"
        )
    rows = np.asarray(truth.datasets["plane_row"][:], dtype=float)
    heights = np.asarray(truth.datasets["plane_height_m"][:], dtype=float)
    pixel_m = recording.scene.distance_m * recording.camera.ifov_rad
    i = int(np.argmin(heights))
    exit_xy = (recording.width / 2 - 0.5, float(rows[i] + heights[i] / pixel_m))
    half = half_width_px if half_width_px is not None else min(50.0, recording.width / 3)
    out = []
    for h, r in zip(heights, rows):
        if max_height_m is not None and h > max_height_m + 1e-9:
            continue
        if heights_m is not None and not any(abs(h - x) < 1e-3 for x in heights_m):
            continue
        if 0 <= r < recording.height:
            out.append(
                Surface(
                    [(exit_xy[0] - half, float(r)), (exit_xy[0] + half, float(r))],
                    name=f"{h * 100:.0f} cm",
                )
            )
    return out, exit_xy
