"""Trust checks of a quantification: inputs that cannot give a rate are
refused (:class:`qogi.errors.UsageError`, :class:`qogi.errors.DataError`);
inputs and results that give a doubtful one are reported as warnings
(:class:`qogi.diagnostics.Diagnostics`, codes documented in
docs/pipeline_api.md).

Each check is one small function the pipeline calls at the stage that knows
the facts (the frame count before reading, the radiance per block, the
result at the end).
"""

from __future__ import annotations

import math
from typing import Optional, Sequence

import numpy as np

from ..diagnostics import Diagnostics
from ..errors import DataError, UsageError

__all__ = [
    "MIN_FRAMES_FLOOR",
    "MIN_FRAMES_RATE",
    "RADIANCE_TEMPERATURE_RANGE_K",
    "check_frame_count",
    "check_source",
    "check_surfaces",
    "RadianceCheck",
    "report_timebase",
    "check_result",
]

#: Below this many frames the velocimetry cannot give a rate at all (the
#: transport's flux level needs 3 frames, a frame velocity a frame on either
#: side): refused with DataError. Given speeds (wind, exit) need 1.
MIN_FRAMES_FLOOR = 5
#: Below this many frames a velocimetry rate is reported with a warning and a
#: velocity term of 100 % of the rate: on 2-4 frames of the lab release the
#: rate read -89 % ... +1535 % (issue 16) -- the transport's time of flight
#: and the temporal scatter are not yet measured.
MIN_FRAMES_RATE = 30
#: Radiometric temperatures [K] that bound a physical band radiance: colder
#: than a clear sky's, hotter than a flare's, are not a scene qogi images.
RADIANCE_TEMPERATURE_RANGE_K = (150.0, 2500.0)


def check_frame_count(n_frames: int, velocity: str, diags: Diagnostics) -> None:
    """Refuses a run too short for any rate; warns below :data:`MIN_FRAMES_RATE`."""
    given = velocity in ("wind", "exit")
    floor = 1 if given else MIN_FRAMES_FLOOR
    if n_frames < floor:
        raise DataError(
            f"{n_frames} frame(s) cannot give an emission rate with the {velocity} velocimetry: "
            f"it needs at least {floor} (a trustworthy rate at least {MIN_FRAMES_RATE}); give a "
            f"longer recording or frame range"
        )
    if not given and n_frames < MIN_FRAMES_RATE:
        diags.add(
            "few-frames",
            f"only {n_frames} frames: a velocimetry rate needs at least {MIN_FRAMES_RATE} "
            f"to be trusted; the velocity term of the interval is set to 100 % of the rate",
            frames=int(n_frames),
            minimum=MIN_FRAMES_RATE,
        )


def check_source(source, width: int, height: int, surfaces: Sequence, diags: Diagnostics) -> None:
    """A source (x, y) [px]: non-finite -> UsageError; outside the image, or
    within a pixel of a surface (its flux then has no defined direction) ->
    warnings ``source-outside-image``, ``source-on-surface``."""
    if source is None:
        return
    x, y = (float(v) for v in source)
    if not (math.isfinite(x) and math.isfinite(y)):
        raise UsageError(f"source must be a finite pixel position x,y; got {source}")
    if not (-0.5 <= x <= width - 0.5 and -0.5 <= y <= height - 0.5):
        diags.add(
            "source-outside-image",
            f"the source ({x:g}, {y:g}) lies outside the {width}x{height} image: the "
            f"surfaces' orientation and the flux level's plume axis are guesses; give the "
            f"source inside the image (or none, to detect it)",
            x=x,
            y=y,
        )
    for s in surfaces:
        d = _distance_to_polyline(np.array([x, y]), np.asarray(s.points, float))
        if d <= 1.0:
            diags.add(
                "source-on-surface",
                f"the source ({x:g}, {y:g}) lies {d:.2f} px from surface {s.name}: which "
                f"side the gas leaves to is undefined there (a sub-pixel shift can flip "
                f"the rate's sign); draw the surface a few pixels downstream",
                surface=s.name,
                distance_px=float(d),
            )


def _distance_to_polyline(p: np.ndarray, pts: np.ndarray) -> float:
    a, b = pts[:-1], pts[1:]
    ab = b - a
    t = np.clip(((p - a) * ab).sum(axis=1) / np.maximum((ab * ab).sum(axis=1), 1e-300), 0, 1)
    q = a + t[:, None] * ab
    return float(np.min(np.hypot(*(p - q).T)))


def check_surfaces(surfaces: Sequence) -> None:
    """A surface shorter than one pixel samples no more than one pixel of the
    plume: its flux is not a flux through a line. Refused (UsageError)."""
    for k, s in enumerate(surfaces):
        if s.length_px < 1.0:
            raise UsageError(
                f"surface {s.name or k + 1} is {s.length_px:.2f} px long; a control "
                f"surface must be at least 1 px long (draw it across the whole "
                f"plume)"
            )


class RadianceCheck:
    """Non-physical band radiance, block by block: a frame whose every pixel
    of a channel is zero, negative, non-finite or outside the radiance of
    :data:`RADIANCE_TEMPERATURE_RANGE_K` is refused (DataError); some such
    pixels give the warning ``radiance-nonphysical`` (counted over the run)."""

    def __init__(self, channels):
        lo, hi = RADIANCE_TEMPERATURE_RANGE_K
        self.low = np.array([ch.band_radiance(lo) for ch in channels], float)
        self.high = np.array([ch.band_radiance(hi) for ch in channels], float)
        self.bad_pixels = 0
        self.total_pixels = 0
        self.first_frame: Optional[int] = None

    def __call__(self, frames: np.ndarray, first_index: int) -> None:
        """``frames`` (B, C, H, W) radiance [W/(m2 sr)]; ``first_index`` the
        recording's index of the first."""
        lo = self.low.astype(np.float32)[None, :, None, None]
        hi = self.high.astype(np.float32)[None, :, None, None]
        bad = ~((frames >= lo) & (frames <= hi))  # NaN counts as bad
        per = bad.reshape(bad.shape[0], bad.shape[1], -1)
        whole = per.all(axis=2)
        if whole.any():
            f, c = (int(v) for v in np.argwhere(whole)[0])
            img = frames[f, c]
            raise DataError(
                f"frame {first_index + f}, channel {c}: no pixel has a physical band radiance "
                f"(min {np.nanmin(img) if np.isfinite(img).any() else float('nan'):.3g}, max "
                f"{np.nanmax(img) if np.isfinite(img).any() else float('nan'):.3g} W/(m2 sr); "
                f"expected {self.low[c]:.3g} ... {self.high[c]:.3g}, the band radiance of "
                f"{RADIANCE_TEMPERATURE_RANGE_K[0]:g}-{RADIANCE_TEMPERATURE_RANGE_K[1]:g} K): "
                f"a blank, corrupt or uncalibrated frame; remove it or choose a frame range "
                f"without it"
            )
        n = int(per.sum())
        if n and self.first_frame is None:
            self.first_frame = first_index + int(np.argmax(per.any(axis=(1, 2))))
        self.bad_pixels += n
        self.total_pixels += int(bad.size)

    def report(self, diags: Diagnostics) -> None:
        if self.bad_pixels:
            diags.add(
                "radiance-nonphysical",
                f"{self.bad_pixels} of {self.total_pixels} pixel values (the first in frame "
                f"{self.first_frame}) are zero, negative or outside the band radiance of "
                f"{RADIANCE_TEMPERATURE_RANGE_K[0]:g}-{RADIANCE_TEMPERATURE_RANGE_K[1]:g} "
                f"K (dead or saturated pixels, a bad calibration); the columns there are "
                f"not trustworthy",
                pixels=self.bad_pixels,
                first_frame=self.first_frame,
            )


def report_timebase(tb, first_frame: int, diags: Diagnostics) -> None:
    """``frames-dropped``: how many frames ``time_s`` says are missing and
    where (recording frame indices), and the gaps the run was cut at."""
    if not tb.dropped:
        return
    where = ", ".join(f"{m} after frame {first_frame + i}" for i, m in tb.dropped[:5])
    more = f" and {len(tb.dropped) - 5} more places" if len(tb.dropped) > 5 else ""
    gaps = tb.gaps
    cut = ""
    if gaps:
        cut = (
            f"; not analysed across {len(gaps)} gap(s) longer than a few frame intervals "
            f"(the longest {max(g for _, g in gaps):.3g} s after frame "
            f"{first_frame + max(gaps, key=lambda x: x[1])[0]})"
        )
    diags.add(
        "frames-dropped",
        f"time_s shows {tb.n_dropped} frame(s) missing: {where}{more}{cut}; velocities use "
        f"the real interval of each pair, and the interval has fewer independent samples",
        dropped=tb.n_dropped,
        places=[[first_frame + i, m] for i, m in tb.dropped[:100]],
        gaps_s=[[first_frame + i, g] for i, g in gaps[:100]],
        segments=len(tb.segments),
    )


def check_result(surfaces, diags: Diagnostics) -> bool:
    """``nan-in-result`` for every surface and species whose mean or interval
    is not finite, ``frames-unquantified`` where some frames' rates are NaN
    (no valid pixel or no velocity there). An interval's end may be
    infinite (a rate nothing bounds: ``speed-not-measured``), never NaN.
    Returns False when the result is not complete (a NaN in a mean or
    interval)."""
    ok = True
    for s in surfaces:
        for sp, r in s.species.items():
            values = [r.mean_kg_h, *r.uncertainty_terms_kg_h.values()]
            if not all(math.isfinite(v) for v in values) or any(math.isnan(v) for v in r.ci90_kg_h):
                ok = False
                diags.add(
                    "nan-in-result",
                    f"the rate of {sp} through {s.surface.name} is not a number "
                    f"(no frame gave a finite flux: no valid column or velocity on the "
                    f"surface); check the surface, the frames and the warnings above",
                    surface=s.surface.name,
                    species=sp,
                )
            bad = int(np.size(r.rate_kg_s) - np.isfinite(r.rate_kg_s).sum())
            if bad and math.isfinite(r.mean_kg_h):
                diags.add(
                    "frames-unquantified",
                    f"{bad} of {np.size(r.rate_kg_s)} frames have no rate of {sp} through "
                    f"{s.surface.name} (no valid pixel or velocity); the mean is of the "
                    f"others",
                    surface=s.surface.name,
                    species=sp,
                    frames=bad,
                )
    return ok
