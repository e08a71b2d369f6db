"""Self-diagnostics per control surface: the evidence, in the run's own data,
that an assumption behind its rate failed.

A rate rests on a background that is right along the surface, an inversion
that found each pixel's column inside its bounds, and a flow that carries
the gas one way through the surface. Each can fail without the rate looking
odd (issue 31: a textured sky read -36 % with 78 % of the surface's
pixel-frames on a bound of the inversion and no warning). Four measures,
per surface, summed over the run's blocks (:class:`SurfaceEvidence`):

* ``at_bound_fraction``: pixel-frames the inversion left on a bound (no
  column inside the bounds fits the contrast: mostly a contrast of the
  wrong sign, i.e. a background on the wrong side of the radiance);
* ``negative_fraction``: pixel-frames whose contrast against the background
  has the sign the gas cannot give (gas warmer than the background raises
  the radiance) by more than 3 noise (pure noise: 0.13 %);
* ``background_residual_noise``: the background's error along the surface
  in units of the camera noise. Per pixel, the low (sign-aware) 5th
  percentile of the contrast over the frames, in noise: a correct
  background gives -1.645 where the gas leaves the pixel (the 5th
  percentile of Gaussian noise), more where it never does, and *less* only
  where the background stands beyond the radiance's own floor, which gas
  cannot cause. The RMS over the surface's pixels of that deficit, times
  sqrt(2) (a background error as likely above the truth as below it, of
  which only the part below shows), is the residual;
* ``reversed_fraction``: the share of the flux through the surface (column
  x normal speed, summed over frames and samples in absolute value) that
  runs against the surface's orientation (the flux level's flow
  reversals);
* ``upwind_contrast_noise``: the RMS contrast, in noise, of the pixels more
  than :data:`UPWIND_MIN_PX` behind the source (against the direction from
  the source to the surfaces), where the gas does not go: a right, static
  background leaves noise there (about 1, or 1.9 against a 5th-percentile
  background); clouds drifting across the frame, or a background estimate
  that misses the scene's structure, leave their contrast. The same for
  every surface of the run; measured only with the source given.

* ``column_fluctuation``: how much the plume's column fluctuates, the
  evidence that its pattern is the gas's: per line across the plume's
  axis (rows of a rising plume) the temporal RMS of the line-integrated
  column (the flux level's transport band) over its mean, and the 90th
  percentile of that over the lines carrying at least a quarter of the
  most-laden line's gas (:func:`column_fluctuation`; the run's blocks
  averaged). The flux level follows the plume's structures; in a quiet,
  nearly laminar column the structures are instability waves that travel
  slower than the gas (issue 31: an independent LES of the lab release read
  -31 % with every interval missing), so a column that hardly fluctuates
  (*below* the threshold) is flagged. Measured with the transport flux
  level only (the fluid velocity and a source).

* ``insensitive_fraction``: the share of the surface's column (summed over
  samples and frames) on samples whose background the gas hardly changes
  (a pipe near the gas's temperature: the contrast is tau (L(T_g) - L_bg),
  thesis eq. 4), whose columns are interpolated from their neighbours
  along the surface (:func:`qogi.pipeline.columns.fill_insensitive`); the
  flux there is unknown up to that share.
* ``plume_residual_noise``: the largest background residual of the run's
  *other* surfaces (:func:`plume_residual`). The velocity comes from one
  field along the whole plume (the flux level follows the column's
  pattern between the surfaces), so a background wrong on one surface
  leaves a static pattern there that moves every surface's rate, however
  clean its own checks (the pipe rack: -70 to -90 % on surfaces whose own
  background read right).
* ``held_background_error``: where the gas never leaves the pixels (the
  plume's base), the background is inpainted from the gas-free pixels
  around; this is that inpainting's error, tried on a ring of known
  pixels around them, over the gas's contrast there
  (:func:`qogi.pipeline.background_choice.held_background_error`; the
  run's, the same for every surface). Above 1 the columns of the plume's
  base are not measured, and the flux level follows them along the whole
  plume (wall-absorption seed 4: -42 % with every other check clean; with
  the true background under the held pixels alone, -19 / -7 / -7 %).

* ``transport_frames_in_view``: how many frames the gas stays in view
  (the frame beyond the source along the flux level's axis over the
  transport's displacement per frame,
  :func:`qogi.pipeline.velocity.frames_in_view`; the run's blocks averaged;
  the same for every surface). Where the gas crosses a good part of the frame
  between frames, its structures change beyond recognition from one frame
  to the next: the flow does not follow them and the time of flight that
  sets the flux level has few of them to match (the operating envelope's
  8 m/s wind at 15 Hz, 52 px per frame of a frame 136 px beyond the
  source: -38 % with tight intervals and no warning). Flagged *below* the
  threshold, and the rate is taken as not measured (term 1). Measured with
  the transport flux level only (the fluid velocity and a source).
  ``transport_unexplained``: the share of the plume's column the time of
  flight does not explain
  (:attr:`qogi.measure.velocimetry.TransportFlux.unexplained`, weighted by
  each line's column, :func:`qogi.pipeline.velocity.transport_unexplained`):
  0.05-0.2 on clean columns at 2-4 m/s and 1.1 at 8 m/s; noise in the
  columns raises it too (1.0-1.9 at a 5 K contrast where the rate read
  within 10 %). Flagged *above* 2, what frames unrelated to each other leave
  (the difference of two independent draws has twice the variance): the fit
  then explains less than no transport at all, and the speed is not
  measured (term 1, the same code): the envelope's wall at -20 K in an
  8 m/s wind, seed 2, read -90 / -70 / -78 % with the fit locked on a slow
  displacement (19.7 frames in view, so the other measure passed).
  ``surface_frames_in_view``: the same frames in view at the surface's own
  column-weighted speed where it is faster than the time of flight's
  (``transport_frames_in_view`` over ``implied_speed_ratio`` when that
  exceeds 1; NaN otherwise): a time of flight that reads the speed low counts too many
  frames in view. Flagged *below* 3.8 (the same code, term 1): on seeds 0-1
  of the operating envelope's wind block the 4 m/s cells reach 3.95-4.45
  and the 8 m/s cells (2.6 frames in view by the truth) 1.97-3.62, their
  geometric midpoint; held out, seeds 2-3: the 8 m/s cells 2.45-3.26, the
  4 m/s ones 3.85-4.14, and the cell whose time of flight read 0.7 of the
  speed (4.7 frames in view by it, +28 / +26 % unwarned) 2.74-2.79.

* ``implied_speed_ratio``: the speed the surface's own columns would need
  to carry the rate through it (its flux over its column, both summed over
  samples and frames: the column-weighted normal speed) over the speed the
  flux level's time of flight measured along the plume
  (:func:`qogi.pipeline.velocity.transport_speed`; the run's blocks
  averaged). A steady core the gas never leaves holds its gas in the
  temporal background, and the columns there vanish while the flux level,
  set by the material beyond, does not: the velocity that carries it then
  reads hundreds to thousands of times the gas's (the textured lab's 2 and
  4 cm surfaces: +57 to +291 % with no other check failing). Infinite where
  the surface's column sums to nothing or less with a flux through it.
  Flagged above the threshold, and the rate is taken as not measured (term
  1). Measured with the transport flux level only (the fluid velocity and
  a source).

Each has a threshold (``THRESHOLDS``; chosen on seeds 0-2 of the structured
presets and reported on seeds 3-5, docs/validation.md; the steady column's
on seeds 0-2 of lab-ch4-5slpm-laminar-gf320, reported on seeds 3-4) beyond
which the surface gets a warning code (``CODES``) and the rate's interval a
relative term sized by the failure (:func:`failure_terms`), so that a rate
the diagnostics call broken is never given a narrow interval.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Dict, List, Optional, Tuple

import numpy as np

__all__ = [
    "SurfaceEvidence",
    "THRESHOLDS",
    "CODES",
    "NEGATIVE_SIGMA",
    "failure_terms",
    "combined_term",
    "upwind_mask",
    "UPWIND_MIN_PX",
    "BELOW",
    "STEADY_COLUMN_TERM",
    "STEADY_COLUMN_SPEED_RATIO",
    "column_fluctuation",
    "plume_residual",
]

#: Contrast below -NEGATIVE_SIGMA noise (the gas's sign) counts as negative.
NEGATIVE_SIGMA = 3.0
#: The 5th percentile of standard Gaussian noise is -Z05.
Z05 = 1.6448536269514722

#: Thresholds of the four measures above which the surface's rate is
#: flagged and its interval widened (fractions, or noise units for the
#: background residual). See docs/pipeline_api.md and docs/validation.md.
THRESHOLDS: Dict[str, float] = {
    "at_bound_fraction": 0.15,
    "negative_fraction": 0.10,
    "background_residual_noise": 4.0,
    "reversed_fraction": 0.15,
    "upwind_contrast_noise": 6.0,
    # Chosen on seeds 0-2 of lab-ch4-5slpm-laminar-gf320 (0.100, 0.091,
    # 0.130) against the lab puff plumes' lowest (0.24, m150; gf320 0.31,
    # sky 0.46): their geometric midpoint, rounded.
    "column_fluctuation": 0.17,
    # Chosen on seeds 0-2 of the structured presets (docs/validation.md).
    "insensitive_fraction": 0.05,
    "plume_residual_noise": 4.0,
    # An error as large as the gas's contrast. On seeds 0-2 of the
    # structured presets the runs that read within 25 % reach 0.92
    # (wall-absorption seed 2), the pipe rack's failing runs 0.90-4.4 (0.90:
    # seed 1, flagged by four other checks); held out, seeds 3-4 are flagged
    # exactly where they fail (docs/validation.md).
    "held_background_error": 1.0,
    # Chosen on seed 0 of the operating envelope's wind scenes (1 kg/h at 10 m
    # before a structured wall, 160x120 px of 1.3 cm at 15 Hz): at 8 m/s
    # (52 px per frame of 136 beyond the source: 2.6) 1.0-4.0, the larger
    # where the fit read the displacement low, at 4 m/s 5.05-5.6; reported on
    # seed 1 (docs/validation.md).
    "transport_frames_in_view": 4.5,
    # Frames unrelated to each other leave twice the anomaly's variance
    # (C_t(k + d) - C_{t+1}(k) of two independent draws): a fit above that
    # explains less than no transport at all. On seeds 0-1 of the operating
    # envelope's wind block (48 runs) no run above it read within 25 %
    # unflagged (the clean ones 0.02-1.9); held out, seeds 2-3 flag the one
    # fit locked on a slow displacement (2.5: -90 % unwarned before;
    # docs/validation.md).
    "transport_unexplained": 2.0,
    # The frames in view at the surface's own speed where faster: chosen
    # on seeds 0-1 of the envelope's wind block between its 8 m/s cells
    # (up to 3.62) and its 4 m/s ones (from 3.95); reported on seeds 2-3
    # (docs/validation.md).
    "surface_frames_in_view": 3.8,
    # Chosen on seeds 0-2 of the validation cases with the source given
    # (docs/validation.md): the surfaces whose columns hold most of the gas
    # reach 8.4 (the textured lab's 8 cm), those holding 1-2 % of it start
    # at 71 (its 6 cm, within 12 % by the luck of the share), every surface
    # off by more than 25 % with no other warning at 2,380 or more; the
    # geometric midpoint of 8.4 and 71, rounded. Reported on seeds 3-4.
    "implied_speed_ratio": 25.0,
}
#: The measures that fail *below* their threshold (the others above it).
#: The measures whose failure says the speed is not measured (the rate's
#: upper end is then unbounded when nothing was detected:
#: qogi.pipeline.budget's ``no-bound-without-speed``).
SPEED_NOT_MEASURED = frozenset(
    {"transport_frames_in_view", "transport_unexplained", "surface_frames_in_view"}
)
BELOW = frozenset({"column_fluctuation", "transport_frames_in_view", "surface_frames_in_view"})
#: The slowest pattern, as a fraction of the gas's speed, that a steady
#: column's interval covers: instability waves of laminar jets and plumes
#: travel at about half to four fifths of the centreline speed.
STEADY_COLUMN_SPEED_RATIO = 0.5
#: The relative 1-sigma term of a steady column: a rate read at
#: STEADY_COLUMN_SPEED_RATIO of the truth reaches it at the interval's far
#: side (interval90's log-normal exp(Z05 term) = 1 / ratio).
STEADY_COLUMN_TERM = -math.log(STEADY_COLUMN_SPEED_RATIO) / Z05
#: A failure term above this (a fraction of the rate) is taken as 1: the
#: rate is not measured (the clouds preset: background contrast behind the
#: source at 0.6 of the gas's contrast on the surface, and the rate 7-10
#: times the truth).
NOT_MEASURED_ABOVE = 0.5
#: Pixels at least this far behind the source [px] make the upwind region.
UPWIND_MIN_PX = 15.0
#: The warning code each measure raises.
CODES: Dict[str, str] = {
    "at_bound_fraction": "inversion-at-bound",
    "negative_fraction": "negative-columns",
    "background_residual_noise": "background-residual",
    "reversed_fraction": "flow-reversed",
    "upwind_contrast_noise": "contrast-upwind",
    "column_fluctuation": "steady-column",
    "insensitive_fraction": "background-insensitive",
    "plume_residual_noise": "background-residual-plume",
    "held_background_error": "background-held",
    "transport_frames_in_view": "transport-unresolved",
    "transport_unexplained": "transport-unresolved",
    "surface_frames_in_view": "transport-unresolved",
    "implied_speed_ratio": "columns-missing",
}


@dataclasses.dataclass
class SurfaceEvidence:
    """The sums behind the measures of one surface (see the module)."""

    pixel_frames: int = 0
    at_bound: int = 0
    negative: int = 0
    deficit_sq: float = 0.0  # sum over pixels of (floor deficit [noise])^2
    pixels: int = 0
    gas_contrast_sum: float = 0.0  # sum of the contrast [noise] on gas pixel-frames
    gas_pixel_frames: int = 0
    #: The flux against the surface and the gross flux (from the run's
    #: :class:`qogi.pipeline.flux_summary.FluxSummary`).
    flux_against: float = 0.0
    flux_abs: float = 0.0
    #: Sum of squared contrasts [noise^2] over the upwind region's
    #: pixel-frames, and their number (the run's, :func:`upwind_mask`).
    upwind_sq: float = 0.0
    upwind_n: int = 0
    #: Sum of the blocks' :func:`column_fluctuation` and their number (the
    #: run's, from the velocity stage).
    fluctuation_sum: float = 0.0
    fluctuation_n: int = 0
    #: The surface's column (the first species', positive parts, summed over
    #: samples and frames [kg/m2]) on samples whose background the gas hardly
    #: changes (interpolated from their neighbours,
    #: :meth:`qogi.pipeline.columns.InvertedColumns._fill_insensitive`), and
    #: in all.
    insensitive_column: float = 0.0
    column_sum: float = 0.0
    #: The largest background residual [noise] of the run's *other*
    #: surfaces, and that surface's mean gas contrast [noise]
    #: (:func:`plume_residual`: set per run, not summed over blocks).
    plume_residual: float = 0.0
    plume_contrast: float = float("nan")
    #: The run's :func:`qogi.pipeline.background_choice.held_background_error`
    #: (set per run, not summed over blocks; NaN without held pixels).
    held_error: float = 0.0
    #: Sum of the blocks' flux-level :func:`qogi.pipeline.velocity.transport_unexplained`
    #: and their number (the run's, from the velocity stage).
    unexplained_sum: float = 0.0
    unexplained_n: int = 0
    #: Sum of the blocks' :func:`qogi.pipeline.velocity.frames_in_view` and
    #: their number (the run's, from the velocity stage).
    in_view_sum: float = 0.0
    in_view_n: int = 0
    #: The surface's column-weighted normal speed: sum |speed| x column and
    #: sum column over samples and frames (the run's
    #: :class:`qogi.pipeline.flux_summary.FluxSummary`), and the sum of the
    #: blocks' flux-level :func:`qogi.pipeline.velocity.transport_speed`
    #: [m/s] and their number.
    surface_speed_num: float = 0.0
    surface_speed_den: float = 0.0
    transport_speed_sum: float = 0.0
    transport_speed_n: int = 0

    @classmethod
    def of(
        cls,
        contrast_noise: np.ndarray,
        at_bound: np.ndarray,
        floor_contrast_noise: Optional[np.ndarray] = None,
    ) -> SurfaceEvidence:
        """The sums of one block: ``contrast_noise`` (T, N) the sign-aware
        contrast (gas positive) of the most sensitive channel in units of
        its noise; ``at_bound`` (T, N) bool, the inversion's status;
        ``floor_contrast_noise`` (T, N), the contrast the background
        residual is measured on, when not the same (against the held
        pixels' inpainting before its bound by their percentile,
        :func:`qogi.pipeline.background_choice.inpaint_held`)."""
        c = np.asarray(contrast_noise, float)
        fc = c if floor_contrast_noise is None else np.asarray(floor_contrast_noise, float)
        ev = cls()
        if c.size == 0:
            return ev
        ev.pixel_frames = int(c.size)
        ev.at_bound = int(np.count_nonzero(at_bound))
        ev.negative = int(np.count_nonzero(c < -NEGATIVE_SIGMA))
        if c.shape[0] >= 20:  # a 5th percentile needs frames
            floor = np.percentile(fc, 5.0, axis=0)
            deficit = np.minimum(0.0, floor + Z05)
            ev.deficit_sq = float(np.sum(deficit**2))
            ev.pixels = int(c.shape[1])
        gas = c > NEGATIVE_SIGMA
        ev.gas_contrast_sum = float(np.sum(c[gas]))
        ev.gas_pixel_frames = int(np.count_nonzero(gas))
        return ev

    def __iadd__(self, other: SurfaceEvidence) -> SurfaceEvidence:
        for f in dataclasses.fields(self):
            setattr(self, f.name, getattr(self, f.name) + getattr(other, f.name))
        return self

    def measures(self) -> Dict[str, float]:
        """The four measures (NaN where there is nothing to measure)."""
        nan = float("nan")
        pf = self.pixel_frames
        return {
            "at_bound_fraction": self.at_bound / pf if pf else nan,
            "negative_fraction": self.negative / pf if pf else nan,
            "background_residual_noise": (
                math.sqrt(2.0 * self.deficit_sq / self.pixels) if self.pixels else nan
            ),
            "reversed_fraction": self.flux_against / self.flux_abs if self.flux_abs > 0 else nan,
            "upwind_contrast_noise": (
                math.sqrt(self.upwind_sq / self.upwind_n) if self.upwind_n else nan
            ),
            "column_fluctuation": (
                self.fluctuation_sum / self.fluctuation_n if self.fluctuation_n else nan
            ),
            "insensitive_fraction": (
                self.insensitive_column / self.column_sum if self.column_sum > 0 else nan
            ),
            "plume_residual_noise": self.plume_residual,
            "held_background_error": self.held_error,
            "transport_unexplained": (
                self.unexplained_sum / self.unexplained_n if self.unexplained_n else nan
            ),
            "transport_frames_in_view": (
                self.in_view_sum / self.in_view_n if self.in_view_n else nan
            ),
            "implied_speed_ratio": self.implied_speed_ratio(),
            "surface_frames_in_view": self.surface_frames_in_view(),
        }

    def surface_frames_in_view(self) -> float:
        """The frames the gas stays in view at the surface's own speed where
        it is faster than the time of flight's (see the module); NaN
        without a time of flight, or where the surface is not faster
        (``transport_frames_in_view`` says it all then)."""
        fiv = self.in_view_sum / self.in_view_n if self.in_view_n else float("nan")
        ratio = self.implied_speed_ratio()
        # An infinite ratio (no column under a flux) is columns-missing's.
        if not (math.isfinite(fiv) and math.isfinite(ratio)) or ratio <= 1.0:
            return float("nan")
        return fiv / ratio

    def implied_speed_ratio(self) -> float:
        """The surface's column-weighted speed over the time of flight's
        (see the module): NaN without a time of flight or a flux through
        the surface, infinite where its column sums to nothing or less."""
        ref = self.transport_speed_sum / self.transport_speed_n if self.transport_speed_n else 0.0
        if not (ref > 0 and self.surface_speed_num > 0):
            return float("nan")
        if not self.surface_speed_den > 0:
            return float("inf")
        return self.surface_speed_num / self.surface_speed_den / ref

    def mean_gas_contrast_noise(self) -> float:
        """Mean contrast [noise] of the pixel-frames with gas (> 3 noise)."""
        return (
            self.gas_contrast_sum / self.gas_pixel_frames if self.gas_pixel_frames else float("nan")
        )


def failure_terms(ev: SurfaceEvidence) -> Tuple[Dict[str, float], List[Tuple[str, float]]]:
    """The measures of a surface, and for each beyond its threshold the
    relative 1-sigma term it adds to the rate's interval:

    * at a bound, negative or insensitive: the fraction itself (the share
      of the pixel-frames, or of the column, that the inversion did not
      measure; the flux through them is unknown up to that share);
    * the plume's residual: that residual over the mean gas contrast of
      the surface it was measured on;
    * the held background's error: the value itself (a relative error of
      the plume base's contrast);
    * background residual, contrast upwind: the residual (the upwind
      contrast) over the mean contrast of the gas on the surface (a
      column changes in proportion to the contrast where the plume is
      thin: a background wrong by r noise moves a column whose contrast
      is C noise by r / C of itself);
    * reversed: twice the fraction (a flux reversed on a share r of the
      gross flux moves the net by 2 r);
    * steady column (below its threshold): :data:`STEADY_COLUMN_TERM`;
    * too few frames in view (below its threshold), a time of flight
      that explains less than unrelated frames, or columns that would need
      many times its speed: 1, the speed is not measured;
    * any of them above :data:`NOT_MEASURED_ABOVE`: 1 (not measured).

    Returns ``(measures, [(measure, term), ...])`` for the measures that
    failed."""
    m = ev.measures()
    failed = []
    for key, limit in THRESHOLDS.items():
        v = m[key]
        beyond = v < limit if key in BELOW else v > limit
        # An infinite speed ratio (no column under a flux) is beyond too.
        if not ((math.isfinite(v) or key == "implied_speed_ratio") and beyond):
            continue
        if key == "column_fluctuation":
            term = STEADY_COLUMN_TERM
        elif key in ("background_residual_noise", "upwind_contrast_noise"):
            c = ev.mean_gas_contrast_noise()
            term = v / c if math.isfinite(c) and c > 0 else 1.0
        elif key == "plume_residual_noise":
            c = ev.plume_contrast
            term = v / c if math.isfinite(c) and c > 0 else 1.0
        elif key == "reversed_fraction":
            term = 2.0 * v
        elif key in (
            "transport_frames_in_view",
            "transport_unexplained",
            "surface_frames_in_view",
            "implied_speed_ratio",
        ):
            term = 1.0
        else:
            term = v
        # Beyond half, the failure is as large as the signal it would
        # correct (clouds as bright as the gas, half the pixel-frames
        # unmeasured): the rate is not measured, the term 100 % (the
        # interval's near side reaches zero, interval90).
        failed.append((key, float(term if term <= NOT_MEASURED_ABOVE else 1.0)))
    return m, failed


def plume_residual(evidence: Dict[int, SurfaceEvidence], j: int) -> Tuple[float, float]:
    """The largest background residual [noise] among the surfaces other
    than ``j`` (``evidence`` per surface index) and that surface's mean gas
    contrast [noise]: ``(0, nan)`` with no other surface.

    The velocity of every surface comes from one field along the whole
    plume (the flux level follows the column's pattern between the
    surfaces): a background wrong on one surface leaves a static pattern in
    that field which moves every surface's rate, its own self-checks clean
    (the pipe rack: a surface whose columns and background read right at
    -70 % while the next surface's background stood 30-250 noise beyond the
    radiance's floor)."""
    worst, contrast = 0.0, float("nan")
    for k, ev in evidence.items():
        if k == j:
            continue
        r = ev.measures()["background_residual_noise"]
        if math.isfinite(r) and r > worst:
            worst, contrast = r, ev.mean_gas_contrast_noise()
    return worst, contrast


def upwind_mask(width: int, height: int, source, surfaces) -> Optional[np.ndarray]:
    """The pixels (H, W) bool more than :data:`UPWIND_MIN_PX` behind the
    source ``(x, y)`` [px] along the direction from it to the surfaces'
    mean midpoint; None without a source, or when fewer than 50 pixels
    qualify."""
    if source is None or not surfaces:
        return None
    mids = np.array([np.asarray(s.points, float).mean(axis=0) for s in surfaces])
    d = mids.mean(axis=0) - np.asarray(source, float)
    norm = float(np.hypot(*d))
    if not norm > 0:
        return None
    d /= norm
    y, x = np.mgrid[0:height, 0:width]
    along = (x - source[0]) * d[0] + (y - source[1]) * d[1]
    mask = along < -UPWIND_MIN_PX
    return mask if mask.sum() >= 50 else None


def combined_term(failed: List[Tuple[str, float]]) -> float:
    """The ``assumptions`` term of a surface: its failed terms in quadrature,
    taken as 1 (not measured) beyond :data:`NOT_MEASURED_ABOVE`, as each
    term alone is; 0 when none failed."""
    total = math.sqrt(sum(t * t for _, t in failed))
    return total if total <= NOT_MEASURED_ABOVE else 1.0


def column_fluctuation(line_sums: np.ndarray) -> float:
    """The plume's column fluctuation (see the module): ``line_sums`` (T, K)
    the column summed over each of K lines across the plume's axis at T
    frames (any unit). Per line with a time-mean of at least a quarter of
    the largest, the temporal RMS over the mean; the 90th percentile over
    those lines. NaN with fewer than 20 frames or no gas (no positive
    mean)."""
    x = np.asarray(line_sums, float)
    if x.ndim != 2 or x.shape[0] < 20:
        return float("nan")
    mean = x.mean(axis=0)
    top = float(np.max(mean)) if mean.size else 0.0
    if not top > 0:
        return float("nan")
    keep = mean >= 0.25 * top
    return float(np.percentile(x[:, keep].std(axis=0) / mean[keep], 90.0))
