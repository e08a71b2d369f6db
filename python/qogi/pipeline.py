"""The quantification pipeline: a recording in, emission-rate time series out.

Stages (docs/pipeline_api.md), for each frame:

1. **Background**: the gas-free band radiance of each channel, beside each
   control surface or a temporal percentile (chosen from the scene by
   default), or from a user region.
2. **Column density**: the contrast ``L - L_bg`` is inverted per pixel for the
   Gaussian-plume parameters (:mod:`qogi.inversion`): single channel with the
   gas temperature given or ambient, or several channels with it inferred;
   column density per species with its 1-sigma uncertainty and a status.
   Pixels on the control surfaces get the full inversion; the velocity field
   around them uses a fast single-channel column proxy (the velocimetry needs
   the shape of the field, not its absolute scale).
3. **Velocity**: velocimetry on the column-density field (default: the
   continuity-equation "fluid" flow), or a given wind / exit speed.
4. **Flux** (thesis eq. 12): ``F = sum_k c_k (v_k . n_k) dl_k`` along each surface,
   per frame and species.
5. **Rate and uncertainty**: the mean of the per-frame rates with a 90 %
   interval combining the temporal standard error (with autocorrelation), the
   column-density uncertainty, the velocimetry's systematic uncertainty, the
   line shape's (:mod:`qogi.budget`) and the background's
   (:mod:`qogi.background`).
6. **Checks** (``Result.warnings``): a rate against the surface's
   orientation or zero while gas crosses it (interval widened), the record
   length a 10 % mean needs, evidence that an assumed gas temperature is
   wrong (:mod:`qogi.hotgas`).

Stages 2-4 run block by block (:mod:`qogi.timebase`: blocks of bounded
length with a few frames of overlap, cut where ``time_s`` has a gap), each
pair's velocity over its real interval; :mod:`qogi.checks` refuses inputs
that cannot give a rate and lists the doubts in ``Result.warnings``.

See docs/pipeline_api.md for the public contract and docs/validation.md for
the measured accuracy.
"""

from __future__ import annotations

import contextvars
import dataclasses
import math
import threading
import time
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .recording import Recording, RecordingError
from .result import Result, SpeciesRate, SurfaceResult
from .surfaces import Region, Surface

__all__ = ["QuantifyConfig", "quantify", "Cancelled", "VELOCITY_SYSTEMATIC"]

#: Relative systematic uncertainty (1 sigma) of the mass-weighted normal
#: velocity for each velocimetry source, used in the uncertainty budget.
#: From the velocimetry study on the synthetic presets (docs/velocimetry.md);
#: "wind" and "exit" are user-given speeds whose relation to the gas velocity at
#: the surface is unknown to qogi and are given a wide band.
VELOCITY_SYSTEMATIC = {"fluid": 0.10, "horn_schunck": 0.25, "lucas_kanade": 0.3,
                       "farneback": 0.3, "dis": 0.3, "piv": 0.2, "wind": 0.5, "exit": 0.5}
#: Relative systematic uncertainty (1 sigma) of column densities from the
#: Gaussian line-of-sight model (profile shape; docs/inversion.md), with the
#: gas temperature given or ambient (columns on the ambient lab release with
#: exact truth maps: ~0.99 of the truth).
COLUMN_SYSTEMATIC = 0.05
#: The same with the temperature inferred on the mixing line: on the heated
#: synthetic plumes with exact truth maps (M150 at 90 C, heated methane at
#: 55 C; docs/validation.md) the inverted columns along the surfaces are
#: 0.83-0.90 of the truth: the Gaussian profile of the mean width is smoother
#: than the filaments it stands for, so the fitted mixing line runs hot. The
#: RMS of those deviations, 0.13, is this default.
COLUMN_SYSTEMATIC_INFERRED = 0.13


class Cancelled(Exception):
    """Raised by :func:`quantify` when its progress callback returns False.
    ``.partial`` holds the Result of the frames finished so far."""

    def __init__(self, message: str, partial: Optional[Result] = None):
        super().__init__(message)
        self.partial = partial


class _Workers:
    """The worker threads of one :func:`quantify` run.

    Every thread a run starts is stopped and joined before the run returns or
    raises (also on Ctrl-C): a thread left inside the engine when the
    interpreter exits is torn down by Python while it holds C++ frames, which
    aborts the process ("FATAL: exception not rethrown"). Long engine calls on
    a worker take :meth:`still_wanted` as their progress callback: the engine
    calls it between chunks and throws when it returns False (Ctrl-C itself
    reaches only the main thread).
    """

    def __init__(self) -> None:
        self.cancel = threading.Event()
        self._done: List[threading.Event] = []

    def still_wanted(self, fraction: float = 0.0) -> bool:
        return not self.cancel.is_set()

    def start(self, target: Callable[[], None], name: str) -> threading.Thread:
        done = threading.Event()

        def run() -> None:
            try:
                target()
            finally:
                done.set()

        job = threading.Thread(target=run, name=name, daemon=True)
        self._done.append(done)
        job.start()
        return job

    def close(self) -> None:
        """Cancel every thread and wait until each has left its target (a
        Ctrl-C while waiting is deferred until they have). Own events, not
        Thread.join: on Python 3.11 a join interrupted by Ctrl-C can mark a
        running thread as stopped."""
        self.cancel.set()
        interrupted = None
        for done in self._done:
            while not done.is_set():
                try:
                    done.wait(0.05)
                except KeyboardInterrupt as e:
                    interrupted = e
        self._done.clear()
        if interrupted is not None:
            raise interrupted


_run_workers: "contextvars.ContextVar[_Workers]" = contextvars.ContextVar("qogi_run_workers")


def _workers() -> _Workers:
    """The current run's :class:`_Workers` (a fresh set outside a run)."""
    w = _run_workers.get(None)
    if w is None:
        w = _Workers()
        _run_workers.set(w)
    return w


_VELOCITY_SOURCES = ("fluid", "horn_schunck", "lucas_kanade", "farneback", "dis", "piv",
                     "wind", "exit")


@dataclasses.dataclass
class QuantifyConfig:
    """Settings of :func:`quantify` (validated on construction; see
    docs/pipeline_api.md for each field)."""

    species: List[str] = dataclasses.field(default_factory=lambda: ["CH4"])
    gas_temperature: Union[str, float] = "ambient"
    velocity: str = "fluid"
    wind_speed_m_s: Optional[float] = None
    exit_velocity_m_s: Optional[float] = None
    averaging: str = "per-frame"
    background: Union[str, Region] = "auto"
    background_percentile: float = 5.0
    source: Optional[Tuple[float, float]] = None
    distance_m: Optional[float] = None
    ambient_temperature_K: Optional[float] = None
    pressure_Pa: Optional[float] = None
    sigma_m: Optional[float] = None
    frames: Optional[Tuple[int, int]] = None
    num_threads: int = 0
    composition: Optional[Dict[str, float]] = None
    column_density: str = "inversion"
    velocity_systematic: Optional[float] = None
    column_systematic: Optional[float] = None
    flux_level: bool = True
    pair_stride: Optional[int] = None
    block_frames: Optional[int] = None
    line_shape: str = "fixed:25+self"
    exit_temperature_K: Optional[float] = None

    def __post_init__(self):
        if isinstance(self.species, str):
            self.species = [self.species]
        self.species = list(self.species)
        if not self.species:
            raise ValueError("species is empty; e.g. species=['CH4']")
        from . import _engine
        for sp in self.species:
            _engine.molar_mass(sp)
        g = self.gas_temperature
        if isinstance(g, str):
            if g not in ("ambient", "infer"):
                raise ValueError(f"gas_temperature must be 'ambient', 'infer' or a temperature in K; got {g!r}")
        elif not (np.isfinite(g) and 150.0 <= float(g) <= 600.0):
            raise ValueError(f"gas_temperature must be within [150, 600] K; got {g}")
        # qogi.velocimetry's method names; the hyphenated spellings are accepted too.
        self.velocity = str(self.velocity).replace("-", "_")
        if self.velocity not in _VELOCITY_SOURCES:
            raise ValueError(f"velocity must be one of {', '.join(_VELOCITY_SOURCES)}; got {self.velocity!r}")
        if self.velocity == "wind" and not (self.wind_speed_m_s is not None and
                                            0 < self.wind_speed_m_s <= 100):
            raise ValueError("velocity='wind' needs wind_speed_m_s within (0, 100] m/s; got "
                             f"{self.wind_speed_m_s}")
        if self.velocity == "exit" and not (self.exit_velocity_m_s is not None and
                                            0 < self.exit_velocity_m_s <= 500):
            raise ValueError("velocity='exit' needs exit_velocity_m_s within (0, 500] m/s; got "
                             f"{self.exit_velocity_m_s}")
        if self.averaging not in ("per-frame", "time-averaged"):
            raise ValueError(f"averaging must be 'per-frame' or 'time-averaged'; got {self.averaging!r}")
        if isinstance(self.background, str):
            if self.background not in ("auto", "beside-surface", "percentile"):
                raise ValueError("background must be 'auto', 'beside-surface', 'percentile' or a "
                                 "qogi.Region; "
                                 f"got {self.background!r}")
        elif not isinstance(self.background, Region):
            raise ValueError(f"background must be a string or a qogi.Region; got {self.background!r}")
        if not 0 <= self.background_percentile <= 50:
            raise ValueError(f"background_percentile must be within [0, 50]; got {self.background_percentile}")
        for name, lo, hi in (("distance_m", 1e-3, 1e5), ("ambient_temperature_K", 180, 350),
                             ("pressure_Pa", 3e4, 1.1e5), ("sigma_m", 1e-4, 10.0)):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} must be within [{lo:g}, {hi:g}]; got {v}")
        if self.frames is not None:
            a, b = self.frames
            if not (0 <= a < b):
                raise ValueError(f"frames must be (start, stop) with 0 <= start < stop; got {self.frames}")
            self.frames = (int(a), int(b))
        if self.column_density not in ("inversion", "truth"):
            raise ValueError(f"column_density must be 'inversion' or 'truth' (validation); got {self.column_density!r}")
        if self.velocity_systematic is not None and not 0 <= self.velocity_systematic <= 1:
            raise ValueError(f"velocity_systematic must be within [0, 1]; got {self.velocity_systematic}")
        if self.column_systematic is not None and not 0 <= self.column_systematic <= 1:
            raise ValueError(f"column_systematic must be within [0, 1]; got {self.column_systematic}")
        if self.pair_stride is not None and (isinstance(self.pair_stride, bool) or
                                             not isinstance(self.pair_stride, int) or
                                             not 1 <= self.pair_stride <= 100):
            raise ValueError(f"pair_stride must be an integer within [1, 100] (frames between "
                             f"the velocimetry's pairs) or None (automatic); got "
                             f"{self.pair_stride!r}")
        if self.block_frames is not None and (isinstance(self.block_frames, bool) or
                                              not isinstance(self.block_frames, int) or
                                              self.block_frames < 8):
            raise ValueError(f"block_frames must be an integer >= 8 (frames streamed per block) "
                             f"or None (automatic); got {self.block_frames!r}")
        from .forward import LineShape
        self.line_shape = str(LineShape.parse(self.line_shape))
        if self.exit_temperature_K is not None and not (
                np.isfinite(self.exit_temperature_K) and 150.0 <= self.exit_temperature_K <= 900.0):
            raise ValueError(f"exit_temperature_K must be within [150, 900] K; got "
                             f"{self.exit_temperature_K}")
        if self.source is not None:
            from .errors import UsageError
            try:
                x, y = (float(v) for v in self.source)
            except (TypeError, ValueError):
                raise UsageError(f"source must be a pixel position (x, y); got "
                                 f"{self.source!r}") from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise UsageError(f"source must be a finite pixel position (x, y); got "
                                 f"({x}, {y})")
            self.source = (x, y)
        if self.composition is not None:
            comp = {str(k): float(v) for k, v in dict(self.composition).items()}
            missing = [sp for sp in self.species if sp not in comp]
            if missing or any(not (np.isfinite(v) and v > 0) for v in comp.values()):
                raise ValueError("composition needs a volume fraction > 0 for every species "
                                 f"quantified ({self.species}); got {self.composition}")
            self.composition = comp

    def to_dict(self) -> dict:
        d = dataclasses.asdict(self)
        if isinstance(self.background, Region):
            d["background"] = dataclasses.asdict(self.background)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> "QuantifyConfig":
        """The config :meth:`to_dict` wrote (JSON-friendly lists accepted);
        unknown keys raise ``qogi.UsageError`` (qogi.config_io)."""
        from .config_io import config_from_dict
        return config_from_dict(d)

    @classmethod
    def from_toml(cls, path) -> "QuantifyConfig":
        """The config of a settings file (TOML, or a result JSON); see qogi.config_io."""
        from .config_io import load_settings
        return load_settings(path).config

    def to_toml(self, path, surfaces=(), units=None) -> None:
        """Write this config (and optionally surfaces and the reporting unit)
        as a settings file that :meth:`from_toml` and ``--config`` read back."""
        from .config_io import write_toml
        write_toml(path, self, surfaces, units)


# ---------------------------------------------------------------------------
# Helpers

def _bilinear(img: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """Sample img (..., H, W) at float pixel positions xy (N, 2) -> (..., N)."""
    h, w = img.shape[-2:]
    x = np.clip(xy[:, 0], 0, w - 1)
    y = np.clip(xy[:, 1], 0, h - 1)
    x0 = np.minimum(np.floor(x).astype(int), w - 2) if w > 1 else np.zeros(len(x), int)
    y0 = np.minimum(np.floor(y).astype(int), h - 2) if h > 1 else np.zeros(len(y), int)
    fx, fy = x - x0, y - y0
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    return (img[..., y0, x0] * (1 - fx) * (1 - fy) + img[..., y0, x1] * fx * (1 - fy)
            + img[..., y1, x0] * (1 - fx) * fy + img[..., y1, x1] * fx * fy)


def _effective_samples(x: np.ndarray) -> float:
    """Effective number of independent samples of a series (integrated
    autocorrelation time, summed until the autocorrelation first drops below
    zero)."""
    x = np.asarray(x, dtype=float)
    x = x[np.isfinite(x)]
    n = len(x)
    if n < 3:
        return float(n)
    d = x - x.mean()
    var = np.dot(d, d) / n
    if var <= 0:
        return float(n)
    tau = 1.0
    for k in range(1, n // 2):
        rho = np.dot(d[:-k], d[k:]) / (n * var)
        if rho <= 0:
            break
        tau += 2 * rho
    return max(1.0, n / tau)


class _Scene:
    """Scene constants of a run (the recording's, overridden by the config)."""

    def __init__(self, rec: Recording, cfg: QuantifyConfig):
        sc = rec.scene
        self.distance_m = cfg.distance_m or sc.distance_m
        self.ambient_K = cfg.ambient_temperature_K or sc.ambient_temperature_K
        self.pressure_Pa = cfg.pressure_Pa or sc.pressure_Pa
        self.ifov = rec.camera.ifov_rad
        self.frame_rate = rec.camera.frame_rate_hz
        self.pixel_m = self.distance_m * self.ifov
        self.m_s_per_px_frame = self.pixel_m * self.frame_rate
        self.netd = rec.camera.netd_K or 0.02
        self.gas_K = (self.ambient_K if cfg.gas_temperature in ("ambient", "infer")
                      else float(cfg.gas_temperature))


def _check_inputs(rec: Recording, surfaces: Sequence[Surface], cfg: QuantifyConfig) -> None:
    if not surfaces:
        raise ValueError("no control surface given; draw one or use qogi.auto_surfaces")
    w, h = rec.width, rec.height
    for k, s in enumerate(surfaces):
        p = np.asarray(s.points)
        if np.any(p[:, 0] < 0) or np.any(p[:, 0] > w - 1) or np.any(p[:, 1] < 0) or \
                np.any(p[:, 1] > h - 1):
            raise ValueError(f"surface {s.name or k} has points outside the {w}x{h} image: {s.points}")
    if cfg.gas_temperature == "infer" and rec.n_channels < 2:
        raise ValueError("gas_temperature='infer' needs a camera with >= 2 channels; this recording "
                         f"has {rec.n_channels}: give the gas temperature or use 'ambient'")
    if cfg.column_density == "truth":
        if rec.truth is None or not all(f"column_density_kg_m2_{sp}" in rec.truth.datasets
                                        for sp in cfg.species):
            raise ValueError("column_density='truth' needs a synthetic recording with truth maps "
                             "(qogi synth ... --truth-maps)")
    if cfg.frames is not None and cfg.frames[1] > rec.n_frames:
        raise ValueError(f"frames {cfg.frames} exceed the recording's {rec.n_frames} frames")
    if isinstance(cfg.background, Region):
        r = cfg.background.clip(w, h)
        if r.x1 <= r.x0 or r.y1 <= r.y0:
            raise ValueError(f"background region {cfg.background} lies outside the {w}x{h} image")


# ---------------------------------------------------------------------------
# Background

class _Background:
    """Gas-free band radiance per channel: along each surface's samples and on
    the analysis region (the latter for the velocity field)."""

    def __init__(self, rec: Recording, cfg: QuantifyConfig, roi: Region, frames: range,
                 channel_sign: np.ndarray, say, typical_temperature_K: float):
        self.cfg = cfg
        self.roi = roi
        self.channel_sign = np.asarray(channel_sign, dtype=float)
        self.typical_temperature_K = typical_temperature_K
        self.percentile_img = None
        # The background's static shape beyond a straight line across the
        # region (set by the run from its time-averaged frames).
        self.shape_correction = None
        if cfg.background == "percentile":
            # Sign-aware: a plume warmer than the background raises radiance,
            # so its background is a low percentile; a colder one a high one.
            sl = roi.slices()
            stack = []
            # At most 200 frames spread over the run bound the memory.
            use = list(frames)[::max(1, len(frames) // 200)]
            for k, f in enumerate(use):
                stack.append(rec.frame(f, quantity="radiance")[:, sl[0], sl[1]])
                if k % 50 == 0:
                    say(0.02 * k / len(use), "background (temporal percentile)")
            stack = np.asarray(stack)
            lo = np.percentile(stack, cfg.background_percentile, axis=0)
            hi = np.percentile(stack, 100 - cfg.background_percentile, axis=0)
            self.percentile_img = np.where(channel_sign[:, None, None] >= 0, lo, hi)

    def region_mean(self, frame: np.ndarray, region: Region) -> np.ndarray:
        """Mean of frames (..., C, H, W) over the region -> (..., C)."""
        r = region.clip(frame.shape[-1], frame.shape[-2])
        return frame[..., r.y0:r.y1, r.x0:r.x1].mean(axis=(-2, -1))

    def along(self, frame: np.ndarray, surface: Surface, xy: np.ndarray, t: np.ndarray) -> np.ndarray:
        """Background radiance (..., C, N) at the surface samples xy of frames
        (..., C, H, W)."""
        cfg = self.cfg
        n = len(xy)
        if isinstance(cfg.background, Region):
            return np.repeat(self.region_mean(frame, cfg.background)[..., None], n, axis=-1)
        if cfg.background == "percentile":
            return np.broadcast_to(_bilinear(self.percentile_img, xy - [self.roi.x0, self.roi.y0]),
                                   frame.shape[:-2] + (n,))
        # Beside the surface: the mean radiance of short stretches just beyond
        # both ends, interpolated linearly along the surface.
        p = np.asarray(surface.points)
        ends = []
        for a, b in ((p[0], p[1]), (p[-1], p[-2])):
            d = (a - b) / np.hypot(*(a - b))
            pts = np.array([a + d * s for s in np.arange(2.0, 8.0, 1.0)])
            h, w = frame.shape[-2:]
            pts[:, 0] = np.clip(pts[:, 0], 0, w - 1)
            pts[:, 1] = np.clip(pts[:, 1], 0, h - 1)
            ends.append(_bilinear(frame, pts).mean(axis=-1))
        return ends[0][..., None] * (1 - t) + ends[1][..., None] * t

    def field(self, frame_roi: np.ndarray, horizontal: bool,
              channel: Optional[int] = None) -> np.ndarray:
        """Background over the analysis region: (C, h, w) for the frame's
        channels (C, h, w), or (h, w) for ``channel`` given one channel's
        (h, w); leading frame axes pass through."""
        cfg = self.cfg
        if isinstance(cfg.background, Region):
            return None
        if cfg.background == "percentile":
            return self.percentile_img if channel is None else self.percentile_img[channel]
        # Per line along the plume, linear between 4-px strips at the region's
        # edges across it, plus the static shape of the background that a
        # straight line misses (a sky's elevation gradient across a
        # wind-blown plume, vignetting): the robust quadratic surface of the
        # time-averaged frames minus its own edge-to-edge interpolation.
        bg = self._edge_interpolation(frame_roi, horizontal)
        if self.shape_correction is not None:
            corr = self.shape_correction[horizontal]
            bg += corr if channel is None else corr[channel]
        return bg

    @staticmethod
    def _edge_interpolation(img: np.ndarray, horizontal: bool) -> np.ndarray:
        k = 4
        if horizontal:  # along x between the left and right strips
            left = img[..., :, :k].mean(axis=-1)
            right = img[..., :, -k:].mean(axis=-1)
            t = np.linspace(0, 1, img.shape[-1]).astype(img.dtype, copy=False)
            out = (right - left)[..., None] * t
            out += left[..., None]
            return out
        top = img[..., :k, :].mean(axis=-2)
        bottom = img[..., -k:, :].mean(axis=-2)
        t = np.linspace(0, 1, img.shape[-2])[:, None].astype(img.dtype, copy=False)
        out = (bottom - top)[..., None, :] * t
        out += top[..., None, :]
        return out

    def set_static_shape(self, mean_roi: np.ndarray) -> None:
        """From the time-averaged region (C, h, w): the background's static
        shape beyond the edge-to-edge interpolation, per orientation, used
        only where the smooth surface describes the gas-free pixels at least
        twice as well as that interpolation does (a plate or a linear
        gradient needs no correction, and gets none)."""
        from .surfaces import _smooth_background

        def mad(r):
            return float(np.median(np.abs(r - np.median(r))))

        smooth = np.stack([_smooth_background(m) for m in mean_roi])
        self.shape_correction = {}
        for o in (True, False):
            lin = self._edge_interpolation(mean_roi, o)
            corr = smooth - self._edge_interpolation(smooth, o)
            use = np.zeros(len(mean_roi), bool)
            for c in range(len(mean_roi)):
                r_smooth = mean_roi[c] - smooth[c]
                free = np.abs(r_smooth - np.median(r_smooth)) <= 2.5 * 1.4826 * mad(r_smooth)
                use[c] = mad((mean_roi[c] - lin[c])[free]) > 2.0 * mad(r_smooth[free])
            self.shape_correction[o] = corr * use[:, None, None]


# ---------------------------------------------------------------------------
# The run

def quantify(recording: Union[Recording, str], surfaces: Sequence[Surface],
             config: Optional[QuantifyConfig] = None,
             progress: Optional[Callable[[float, str], Optional[bool]]] = None,
             keep_maps: bool = False) -> Result:
    """Emission-rate time series of each species through each control surface.

    Parameters
    ----------
    recording : qogi.Recording or path
    surfaces : list of qogi.Surface
        Lines or polylines in pixel coordinates; sign convention in
        :mod:`qogi.surfaces` (left-hand normal positive), or oriented away from
        ``config.source`` when given.
    config : QuantifyConfig, optional
    progress : callable(fraction, message) -> bool or None
        Returning False cancels: :class:`Cancelled` is raised with the partial
        result of the frames finished so far.
    keep_maps : bool
        Keep per-frame column-density and velocity maps (``Result.maps``).

    Returns
    -------
    qogi.Result
    """
    from .recording import open_recording

    cfg = config or QuantifyConfig()
    rec = open_recording(recording) if not isinstance(recording, Recording) else recording
    surfaces = [s if isinstance(s, Surface) else Surface(s) for s in surfaces]
    surfaces = [Surface(s.points, s.name or f"S{k + 1}") for k, s in enumerate(surfaces)]
    if cfg.source is not None:
        surfaces = [s.oriented_away_from(cfg.source) for s in surfaces]
    _check_inputs(rec, surfaces, cfg)
    from .checks import check_surfaces
    check_surfaces(surfaces)
    workers = _Workers()
    token = _run_workers.set(workers)
    try:
        result = _run(rec, surfaces, cfg, progress, keep_maps)
    finally:
        _run_workers.reset(token)
        workers.close()
    # What opening a camera file noticed (scene facts at factory defaults,
    # assumed pressure, dropped frames) and where each scene fact came from.
    # (Dropped frames are the pipeline's own finding too: reported once.)
    result.warnings.extend_unique(
        w for w in (getattr(rec, "warnings", None) or ())
        if not (w.code == "frames-dropped" and result.warnings.has("frames-dropped")))
    if getattr(rec, "scene_origin", None):
        result.info["scene_origin"] = dict(rec.scene_origin)
    return result


class _TruthColumns:
    """Column densities from a synthetic recording's truth maps (validation:
    isolates the velocimetry and flux from the inversion)."""

    def __init__(self, rec: Recording, cfg: QuantifyConfig):
        self.ds = {sp: rec.truth.datasets[f"column_density_kg_m2_{sp}"] for sp in cfg.species}

    def frame(self, f: int, roi: Region) -> Dict[str, np.ndarray]:
        sl = roi.slices()
        return {sp: np.asarray(d[f, sl[0], sl[1]], dtype=np.float64) for sp, d in self.ds.items()}


#: InversionResult fields per pixel: arrays, and dicts of arrays per species.
_RESULT_ARRAYS = ("status", "bound_mask", "flags", "parameters", "parameter_sigma", "covariance",
                  "chi2", "condition_number", "iterations")
_RESULT_DICTS = ("column_density", "column_density_sigma", "path_concentration_ppm_m",
                 "path_concentration_sigma_ppm_m")


def _merge_results(a, b, sel: np.ndarray):
    """InversionResult ``a`` (pixels on the first axis) with the pixels
    selected by ``sel`` taken from ``b``."""
    import copy
    out = copy.copy(a)
    for name in _RESULT_ARRAYS:
        x = np.array(getattr(a, name))
        x[sel] = np.asarray(getattr(b, name))[sel]
        setattr(out, name, x)
    for name in _RESULT_DICTS:
        d = {}
        for sp, v in getattr(a, name).items():
            x = np.array(v)
            x[sel] = np.asarray(getattr(b, name)[sp])[sel]
            d[sp] = x
        setattr(out, name, d)
    return out


def _owned(result):
    """A copy of an InversionResult whose arrays may be written."""
    import copy
    out = copy.copy(result)
    for name in _RESULT_ARRAYS:
        setattr(out, name, np.array(getattr(result, name)))
    for name in _RESULT_DICTS:
        setattr(out, name, {sp: np.array(v) for sp, v in getattr(result, name).items()})
    return out


def _scatter(full, part, idx: np.ndarray) -> None:
    """Writes InversionResult ``part`` (pixels ``idx`` of ``full``) into ``full``."""
    for name in _RESULT_ARRAYS:
        getattr(full, name)[idx] = getattr(part, name)
    for name in _RESULT_DICTS:
        for sp, v in getattr(part, name).items():
            getattr(full, name)[sp][idx] = v


def _weighted_median(values: np.ndarray, weights: np.ndarray) -> float:
    """The value below which half the total weight lies."""
    order = np.argsort(values)
    v, w = np.asarray(values, float)[order], np.asarray(weights, float)[order]
    c = np.cumsum(w)
    return float(v[np.searchsorted(c, 0.5 * c[-1])])


def _gaussian_width(profile: np.ndarray, cut: float = 0.2) -> float:
    """Standard deviation [samples] of a Gaussian-like profile from the second
    moment of its part above ``cut`` x its maximum (noise in the wings would
    inflate a plain second moment), corrected for the truncation: for a
    Gaussian cut at z_c = sqrt(2 ln(1/cut)) the moment is
    sigma^2 (1 - 2 z_c phi(z_c) / (2 Phi(z_c) - 1))."""
    p = np.asarray(profile, dtype=float)
    p = np.where(np.isfinite(p), p, 0.0)
    top = p.max() if p.size else 0.0
    if not top > 0:
        return float("nan")
    w = np.where(p > cut * top, p, 0.0)
    s = np.arange(p.size, dtype=float)
    tot = w.sum()
    mean = (w * s).sum() / tot
    var = (w * (s - mean) ** 2).sum() / tot
    zc = math.sqrt(2.0 * math.log(1.0 / cut))
    phi = math.exp(-0.5 * zc * zc) / math.sqrt(2.0 * math.pi)
    big_phi = 0.5 * (1.0 + math.erf(zc / math.sqrt(2.0)))
    factor = 1.0 - 2.0 * zc * phi / (2.0 * big_phi - 1.0)
    return math.sqrt(var / factor)


class _InvertedColumns:
    """Column densities by the per-pixel inversion (qogi.inversion).

    Surface samples get the configured inversion (single channel with the gas
    temperature given or ambient, or every channel with the temperature
    inferred), with the plume depth sigma from the plume's width across the
    surface (axisymmetric plume) unless given. The velocity field around the
    surfaces uses a single-channel column proxy at the assumed gas
    temperature (Newton inversion, fast): velocimetry needs the field's shape,
    not its absolute scale.
    """

    def __init__(self, rec: Recording, cfg: QuantifyConfig, scene: _Scene, roi: Region,
                 horizontal: bool, background: "_Background"):
        from . import inversion as inv
        from .forward import forward_model

        self.rec, self.cfg, self.scene, self.roi = rec, cfg, scene, roi
        self.horizontal = horizontal
        self.background = background
        channels = rec.channels
        self.model = forward_model(channels, cfg.species, scene.pressure_Pa,
                                   line_shape=cfg.line_shape)
        netd = rec.camera.netd_K or 0.02
        if cfg.gas_temperature == "infer":
            self.temperature_range_K = (scene.ambient_K - 10.0, scene.ambient_K + 150.0)
            temperature = inv.free(*self.temperature_range_K)
        else:
            self.temperature_range_K = (scene.gas_K - 10.0, scene.gas_K + 10.0)
            temperature = inv.fixed(scene.gas_K)
        # One per-scene table serves every inversion of the run. Over the
        # 160 K of an inferred temperature, 10 K nodes: the cubic spline in T
        # then differs from the 5 K table by <= 2e-3 (median 3e-6) of the
        # contrast, well inside the fast model's own 0.5 % (docs/pipeline_api.md),
        # at half the build time; and 6 nodes per decade of u = x sigma
        # instead of 8: within 0.34 NETD (99 %: 0.08) of the 8-node table on
        # the lab domain (x 1e-4 to 1, sigma 1 mm to 30 cm, 12-147 C), 22 %
        # less build time.
        # It is built on a worker thread (the engine releases the GIL) while
        # the frames are read; the first use of :attr:`table` waits for it.
        infer = cfg.gas_temperature == "infer"
        table_kw = dict(min_peak_temperature_K=self.temperature_range_K[0],
                        max_peak_temperature_K=self.temperature_range_K[1],
                        temperature_step_K=10.0 if infer else 5.0,
                        nodes_per_decade=6 if infer else 8,
                        num_threads=cfg.num_threads)
        self._table, self._table_error = None, None

        line_solver = infer and (cfg.composition is not None or len(cfg.species) == 1)

        workers = _workers()

        def build() -> None:
            try:
                self._table = inv.scene_table(self.model, scene.ambient_K,
                                              progress=workers.still_wanted, **table_kw)
                if line_solver and self._table is not None and workers.still_wanted():
                    inv._line_inverter(self._table)  # its band tables, cached
            except BaseException as e:  # re-raised on the caller's thread
                self._table_error = e

        self._table_job = workers.start(build, "qogi-scene-table")
        # The other line-shape rules, for the budget's line-shape term.
        from .budget import AlternativeModels
        self.alternatives = AlternativeModels(channels, cfg.species, scene.pressure_Pa,
                                              cfg.line_shape, start=workers.start)
        self.k_K_per_fraction, self.k_sigma, self.k_relative_effect = None, 0.0, 0.0
        self.mixing_pixels = 0
        # A known composition ties the species' fractions (then the ratios of
        # the bands' contrasts measure the temperature); otherwise each is free.
        fractions = None
        if cfg.composition is not None and len(cfg.species) > 1:
            ref = cfg.species[0]
            fractions = {ref: "free"}
            for sp in cfg.species[1:]:
                fractions[sp] = inv.tied(ref, cfg.composition[sp] / cfg.composition[ref])
        self._inv_kw = dict(netd_K=netd, fractions=fractions, temperature=temperature,
                            num_threads=cfg.num_threads)
        self.inv_module = inv
        # The velocity proxy: a monotone lookup from the contrast of the
        # channel most sensitive to the first species to its column density,
        # at the assumed gas temperature, a typical depth and the scene's
        # background (velocimetry needs the field's shape, not its scale).
        bg_t = background.typical_temperature_K
        self._bg_t = bg_t
        contrast = self._contrast({cfg.species[0]: np.array([1e-3])}, np.array([scene.gas_K]),
                                  np.array([0.02]), use_table=False)[0]
        sens = [abs(contrast[c]) / (netd * ch.band_radiance_derivative(bg_t))
                for c, ch in enumerate(channels)]
        self.proxy_channel = int(np.argmax(sens))
        self._set_proxy_lookup(0.0 if cfg.gas_temperature == "infer" else None)
        self.sigma_m: Dict[int, float] = {}

    def start_block(self) -> None:
        """Forgets the samples collected for the previous block (the pipeline
        streams a run in blocks); with the temperature inferred, the proxy's
        mixing line is measured again on the block."""
        for name in ("_rad", "_bg", "_prof"):
            if hasattr(self, name):
                delattr(self, name)
        if self.cfg.gas_temperature == "infer" and self._k_proxy != 0.0:
            self._set_proxy_lookup(0.0)

    def _set_proxy_lookup(self, k_K_per_fraction: Optional[float]) -> None:
        """The contrast -> column lookups of the velocity proxy: at the assumed
        gas temperature (None), or along the plume's mixing line
        T_peak = T_amb + k x once the temperature has been inferred, for a
        grid of plume depths (see :meth:`contrast_to_column`)."""
        self._k_proxy = k_K_per_fraction
        self._proxy_nodes = None  # made on first use (needs the table)
        self._grid = None

    @property
    def table(self):
        """The per-scene table (waits for the worker building it)."""
        if self._table_job is not None:
            self._table_job.join()
            self._table_job = None
        if self._table_error is not None:
            raise self._table_error
        return self._table

    @property
    def proxy_nodes(self):
        if self._proxy_nodes is None:
            self._proxy_nodes = self._lookup_nodes(np.array([self.cfg.sigma_m or 0.02]))[0]
        return self._proxy_nodes

    def _lookup_nodes(self, sigmas: np.ndarray) -> list:
        """(contrast, column) nodes of the monotone lookup per depth."""
        cfg, scene = self.cfg, self.scene
        x = np.geomspace(1e-7, 1.0, 64)
        if self._k_proxy is None:
            t = np.full_like(x, scene.gas_K)
        else:
            lo, hi = self.temperature_range_K
            t = np.clip(scene.ambient_K + self._k_proxy * x, lo, hi)
        # x: the released gas's total peak fraction (the mixing line's x).
        fr = {cfg.species[0]: x}
        if cfg.composition is not None:
            total = sum(cfg.composition[sp] for sp in cfg.species)
            fr = {sp: x * cfg.composition[sp] / total for sp in cfg.species}
        n, m = len(sigmas), len(x)
        frs = {sp: np.tile(v, n) for sp, v in fr.items()}
        ts = np.tile(t, n)
        sg = np.repeat(np.asarray(sigmas, float), m)
        contrast = np.abs(self._contrast(frs, ts, sg)[:, self.proxy_channel]).reshape(n, m)
        cols = self.model.column_density(frs, ts, sg, scene.ambient_K)[cfg.species[0]].reshape(n, m)
        out = []
        for i in range(n):
            keep = np.concatenate([[True], np.diff(contrast[i]) > 0])
            out.append((np.concatenate([[0.0], contrast[i][keep]]),
                        np.concatenate([[0.0], cols[i][keep]])))
        return out

    def line_shape_curves(self, j: int, species: str):
        """(columns, ratios) of :func:`qogi.budget.line_shape_ratios` for
        surface ``j``: the proxy channel, the surface's depth, the assumed
        gas temperature or the fitted mixing line."""
        from .budget import fractions_of, line_shape_ratios

        cfg, scene = self.cfg, self.scene
        fractions = fractions_of(cfg, species)

        def temperature(x):
            if self.k_K_per_fraction is None:
                return np.full_like(x, scene.gas_K)
            lo, hi = self.temperature_range_K
            return np.clip(scene.ambient_K + self.k_K_per_fraction * x, lo, hi)

        models = [m for _, m in self.alternatives.get()]
        return line_shape_ratios(self.model, models, self.proxy_channel, fractions, temperature,
                                 self.sigma_m.get(j, cfg.sigma_m or 0.02), scene.ambient_K,
                                 self._bg_t, species)

    def _contrast(self, fractions: Dict[str, np.ndarray], peak_temperature_K: np.ndarray,
                  sigma_m: np.ndarray, use_table: bool = True) -> np.ndarray:
        """Contrast (N, C) [W/(m2 sr)] of Gaussian plumes in front of the
        scene's typical background: from the per-scene table when there is
        one (thousands of times faster), else from the fast model."""
        tp = np.asarray(peak_temperature_K, float)
        sg = np.asarray(sigma_m, float)
        if use_table and self.table is not None:
            x = np.stack([np.asarray(fractions.get(sp, np.zeros_like(tp)), float)
                          for sp in self.cfg.species], axis=1)
            tbg = np.full((tp.size, len(self.rec.channels)), float(self._bg_t))
            return np.asarray(self.table.contrast(np.ascontiguousarray(x), tp, sg, tbg)[0])
        l = self.model.band_radiance(fractions, tp, sg, self.scene.ambient_K, self._bg_t)
        return l - np.array([ch.band_radiance(self._bg_t) for ch in self.rec.channels])

    def mean_contrast_snr(self, j: int) -> Optional[np.ndarray]:
        """The time-averaged proxy-channel contrast along surface ``j`` in
        units of its noise (per-frame NETD noise / sqrt(frames)); None
        without stored profiles."""
        prof = getattr(self, "_prof", None)
        if not prof:
            return None
        ch = self.rec.channels[self.proxy_channel]
        netd = np.broadcast_to(np.asarray(self._inv_kw["netd_K"], float),
                               (len(self.rec.channels),))[self.proxy_channel]
        noise = netd * float(ch.band_radiance_derivative(self._bg_t)) / math.sqrt(len(prof))
        return np.mean([p[j] for p in prof], axis=0) / noise

    def _lookup(self, contrast, nodes=None) -> np.ndarray:
        c = np.asarray(contrast)
        nc, ncol = nodes if nodes is not None else self.proxy_nodes
        return np.sign(c) * np.interp(np.abs(c), nc, ncol)

    def contrast_to_column(self, contrast: np.ndarray) -> np.ndarray:
        """Signed proxy contrast fields (T, H, W) -> column proxy, in place.

        The velocimetry's mass balance needs a field proportional to the
        column all along the plume, and a single-channel lookup depends on the
        plume's depth (saturation): the depth grows downstream. Without a
        given depth, each line across the plume (rows for horizontal
        surfaces, columns otherwise) gets the lookup of its own depth, the
        Gaussian width of the time-averaged plume across that line
        (axisymmetric plume), interpolated between lookups on a grid of
        depths; lines without a measurable plume take the nearest line's."""
        if self.cfg.sigma_m is not None or contrast.shape[0] == 0:
            for k in range(contrast.shape[0]):
                contrast[k] = self._lookup(contrast[k])
            return contrast
        view = contrast if self.horizontal else contrast.transpose(0, 2, 1)
        mean = self._lookup(view.mean(axis=0))              # (lines, across)
        top = mean.max()
        lines = np.arange(mean.shape[0])
        widths = np.full(mean.shape[0], np.nan)
        for r in lines:
            if top > 0 and mean[r].max() > 0.05 * top:
                widths[r] = _gaussian_width(mean[r]) * self.scene.pixel_m
        ok = np.isfinite(widths) & (widths > 0)
        if not ok.any():
            for k in range(contrast.shape[0]):
                contrast[k] = self._lookup(contrast[k])
            return contrast
        widths = np.interp(lines, lines[ok], widths[ok])
        grid = np.geomspace(0.002, 0.5, 9)
        nodes = self._lookup_nodes(grid)
        u = np.interp(np.log(np.clip(widths, grid[0], grid[-1])), np.log(grid),
                      np.arange(grid.size))
        j0 = np.minimum(np.floor(u).astype(int), grid.size - 2)
        self.line_depths_m = widths
        from . import _engine

        # Every value through its line's two depth lookups (the engine's
        # LookupLines: numpy.interp per node table, blended per line), on a
        # contiguous copy when the field is a view.
        m = max(len(c) for c, _ in nodes)
        xs = np.array([np.pad(c, (0, m - len(c)), mode="edge") for c, _ in nodes])
        ys = np.array([np.pad(k, (0, m - len(k)), mode="edge") for _, k in nodes])
        work = contrast if (contrast.flags.c_contiguous and contrast.dtype == np.float32) \
            else np.ascontiguousarray(contrast, dtype=np.float32)
        _engine.lookup_lines(work, bool(self.horizontal), xs, ys, j0.astype(np.int32),
                             np.clip(u - j0, 0.0, 1.0), num_threads=self.cfg.num_threads)
        if work is not contrast:
            contrast[...] = work
        return contrast

    def proxy_field(self, frame: np.ndarray, out: Optional[np.ndarray] = None) -> np.ndarray:
        """The signed proxy-channel contrast of frames (..., C, H, W) over the
        region -> (..., h, w) float32 (into ``out`` when given)."""
        sl = self.roi.slices()
        c = self.proxy_channel
        # In float32 (the frames' own precision; its rounding, ~1e-7 of the
        # radiance, is ~1e-4 of the NETD noise).
        fr = frame[..., c, sl[0], sl[1]]
        bg = self.background.field(fr, self.horizontal, channel=c)
        if bg is None:  # a uniform region background
            bg = self.background.region_mean(frame, self.cfg.background)[..., c, None, None]
        # Signed (gas contrast positive): noise averages out of the sums the
        # velocimetry's flux level takes along the plume.
        dl = np.subtract(fr, bg, out=out, dtype=np.float32)
        dl *= np.float32(self.background.channel_sign[c])
        return dl

    def collect(self, frames: np.ndarray, surfaces: Sequence[Surface], samples,
                out: Optional[np.ndarray] = None) -> np.ndarray:
        """The signed proxy-channel contrast fields (B, h, w) of a block of
        frames (B, C, H, W) (into ``out`` when given), converted to a column
        proxy by :meth:`contrast_to_column` once the lookup is final; stores
        the radiance and the background at the surface samples for
        :meth:`finish`."""
        field = self.proxy_field(frames, out)
        origin = [self.roi.x0, self.roi.y0]
        rad, bg, prof = [], [], []
        for s, (xy, n, dl, t) in zip(surfaces, samples):
            rad.append(_bilinear(frames, xy))
            bg.append(self.background.along(frames, s, xy, t))
            prof.append(_bilinear(field, xy - origin))
        if not hasattr(self, "_rad"):
            self._rad, self._bg, self._prof = [], [], []
        self._rad.extend(np.concatenate(rad, axis=-1))
        self._bg.extend(np.concatenate(bg, axis=-1))
        self._prof.extend([p[i] for p in prof] for i in range(len(frames)))
        return field

    def finish(self, samples, time_averaged: bool = False, progress=None, alongside=None):
        """Inverts the stored samples of every frame in one call. Returns per
        surface ``(columns {sp: (T, N)}, sigmas {sp: (T, N)})`` and the status
        counts. ``alongside`` (optional callable) runs on a worker thread while
        the per-pixel solve runs once the proxy lookup is final (with the
        temperature inferred), else after it; its exception is re-raised.
        The plume depth of each surface is the Gaussian width of its
        time-averaged proxy column profile (axisymmetric plume), unless given."""
        from . import inversion as inv

        nt = len(self._rad)
        sizes = [len(x[0]) for x in samples]
        edges = np.concatenate([[0], np.cumsum(sizes)])
        sig = np.empty(edges[-1])
        for j in range(len(samples)):
            if self.cfg.sigma_m is not None:
                sigma = self.cfg.sigma_m
            else:
                mean_prof = np.mean([self._lookup(p[j]) for p in self._prof], axis=0)
                sigma = _gaussian_width(mean_prof) * self.scene.pixel_m
                if not (np.isfinite(sigma) and sigma > 0):
                    sigma = 0.02
            self.sigma_m[j] = float(sigma)
            sig[edges[j]:edges[j + 1]] = sigma
        rad = np.asarray(self._rad)          # (T, C, N)
        bg = np.asarray(self._bg)
        # The plume depth: given, or the width of the time-averaged plume
        # across each surface (axisymmetric plume), held fixed with one
        # channel and as a Gaussian prior (50 %) when the temperature is
        # inferred (a free depth is nearly degenerate with the fractions).
        if self.cfg.sigma_m is not None or self.cfg.gas_temperature != "infer":
            sigma_param = inv.fixed(float(np.median(sig)))
            sigma_pixels = sig
        else:
            sigma_param = None
            sigma_pixels = sig
        if self.cfg.gas_temperature == "infer" and not time_averaged:
            return self._finish_mixing(rad, bg, sig, edges, len(samples), progress, alongside)
        if time_averaged:
            res = self._invert(rad.mean(axis=0), bg.mean(axis=0), sigma_pixels, sigma_param,
                               noise_scale=1.0 / math.sqrt(nt), progress=progress)
            res_cols = {sp: np.repeat(res.column_density[sp][None], nt, axis=0)
                        for sp in self.cfg.species}
            res_sig = {sp: np.repeat(res.column_density_sigma[sp][None], nt, axis=0)
                       for sp in self.cfg.species}
            ok = np.repeat((res.valid | (res.status == inv.BELOW_DETECTION))[None], nt, axis=0)
            counts = res.counts()
        else:
            # Every frame's pixels in one call, each from the coarse table
            # guess: warm starts from the previous frame can follow the wrong
            # branch of the temperature-column ambiguity of hot plumes.
            c_, n_ = rad.shape[1], rad.shape[2]
            flat = self._invert(rad.transpose(1, 0, 2).reshape(c_, nt * n_),
                                bg.transpose(1, 0, 2).reshape(c_, nt * n_),
                                np.tile(sigma_pixels, nt), sigma_param, 1.0, progress)
            res_cols = {sp: flat.column_density[sp].reshape(nt, n_) for sp in self.cfg.species}
            res_sig = {sp: flat.column_density_sigma[sp].reshape(nt, n_) for sp in self.cfg.species}
            ok = (flat.valid | (flat.status == inv.BELOW_DETECTION)).reshape(nt, n_)
            counts = flat.counts()
        out = []
        for j in range(len(samples)):
            a, b = edges[j], edges[j + 1]
            cols = {sp: np.where(ok[:, a:b], res_cols[sp][:, a:b], np.nan) for sp in self.cfg.species}
            sigs = {sp: np.where(ok[:, a:b], res_sig[sp][:, a:b], 0.0) for sp in self.cfg.species}
            out.append((cols, sigs))
        if alongside is not None:
            alongside()
        return out, counts

    # -- the inferred gas temperature, frame by frame -----------------------------
    def _finish_mixing(self, rad, bg, sig, edges, n_surfaces, progress, alongside=None):
        """Per-frame columns with the gas temperature inferred through the
        plume's mixing line.

        A released gas that mixes with the ambient air (adiabatically, as in
        a plume) has, at every point, a temperature excess proportional to
        its volume fraction: T - T_amb = k x (the Gaussian line-of-sight model
        has this shape: both follow g(s)). One k holds for the whole scene,
        so it is measured once: on a random sample (<= 3000) of the
        pixel-frames with contrast >= 10x noise solved on the line for each k
        of a 10 K grid, k minimises the summed chi2 (each pixel's capped at
        50), refined by a parabola; its 1-sigma is where that profile rises
        by the reduced chi2. Then each pixel-frame has one unknown, x,
        with T_peak = T_amb + k x: with a known composition (or one species)
        its least-squares value on the line (qogi.inversion.
        invert_on_mixing_line: a coarse scan and Gauss-Newton in ln x on the
        scene table, ~40,000 px/s per core); otherwise a root of x = g(x) (g:
        the fixed-temperature inversion at T(x)) by bracketed regula falsi,
        each step one fast fixed-temperature pass over the pixels not yet
        converged. This avoids the two-branch
        (thin-hot / thick-cool) ambiguity of free per-pixel temperatures in
        noisy frames and costs one line solve instead of a multi-start
        four-parameter solve per pixel. The uncertainty of k is
        carried into the column-density term (:attr:`k_relative_effect`).
        """
        inv = self.inv_module
        cfg, t_amb = self.cfg, self.scene.ambient_K
        nt, nc, n = rad.shape
        lo, hi = self.temperature_range_K
        r2 = rad.transpose(1, 0, 2).reshape(nc, nt * n)
        b2 = bg.transpose(1, 0, 2).reshape(nc, nt * n)
        s2 = np.tile(sig, nt)
        kw = dict(self._inv_kw)
        kw.pop("temperature")
        fixed = []  # the fixed-temperature inversion of the fixed-point passes, made on use

        def fixed_t():
            if not fixed:
                fixed.append(inv.Inversion(self.model, t_amb, temperature=inv.fixed(t_amb),
                                           sigma_m=0.05, temperature_range_K=(lo, hi),
                                           table=self.table, **kw))
            return fixed[0]

        def stage(a, b, label):
            return lambda f: progress(a + (b - a) * f) if progress else None

        # 2. Every pixel-frame: x = g(x) with T_peak = T_amb + k x. In u = ln x
        # the root of phi(u) = ln g(e^u) - u is bracketed by x -> 0 (g(0) > 0:
        # phi > 0) and x = g(0) (phi <= 0 when g decreases, as it does for gas
        # warmer than its background); the Illinois variant of regula falsi
        # closes the bracket, each step one fixed-temperature pass over the
        # pixels not yet within 0.3 % of their root.
        def g(xv, kk, idx, a, b):
            t = np.clip(t_amb + kk * xv, lo, hi)
            res = fixed_t().invert(r2[:, idx], background_radiance=b2[:, idx], sigma_m=s2[idx],
                                 peak_temperature_K=t, progress=stage(a, b, "columns"))
            return res, sum(res.peak_fraction[sp] for sp in cfg.species)

        def solve_passes(kk, idx, a, b, passes=7):
            span = (b - a) / passes
            out, g0 = g(np.zeros(idx.size), kk, idx, a, a + span)
            out = _owned(out)
            live = np.flatnonzero((g0 > 0) & out.valid)
            ua = np.full(live.size, math.log(1e-7))
            fa = np.log(g0[live]) - ua                      # > 0
            ub = np.log(np.minimum(g0[live], 1.0))
            res, gb = g(np.exp(ub), kk, idx[live], a + span, a + 2 * span)
            fb = np.log(np.maximum(gb, 1e-12)) - ub
            _scatter(out, res, live)
            # No bracket (g not decreasing there): keep the pass at x = g(0).
            keep = (fb < 0) & (np.abs(fb) > 3e-3)
            live, ua, fa, ub, fb = live[keep], ua[keep], fa[keep], ub[keep], fb[keep]
            side = np.zeros(live.size, int)
            for step in range(passes - 2):
                if live.size == 0:
                    break
                uc = (ua * fb - ub * fa) / (fb - fa)
                res, gc = g(np.exp(uc), kk, idx[live], a + (2 + step) * span,
                            a + (3 + step) * span)
                fc = np.log(np.maximum(gc, 1e-12)) - uc
                _scatter(out, res, live)
                pos = fc > 0  # the root lies above uc: uc replaces the lower end
                # Illinois: an end kept twice in a row has its value halved.
                fa = np.where(pos, fc, np.where(side == -1, 0.5 * fa, fa))
                fb = np.where(~pos, fc, np.where(side == 1, 0.5 * fb, fb))
                ua = np.where(pos, uc, ua)
                ub = np.where(~pos, uc, ub)
                side = np.where(pos, 1, -1)
                keep = np.abs(fc) > 3e-3
                live, ua, fa, ub, fb, side = (live[keep], ua[keep], fa[keep], ub[keep], fb[keep],
                                              side[keep])
            return out


        # With a known composition (or one species) each pixel-frame is one
        # least-squares problem on the line (the engine's mixing-line
        # inverter: a coarse scan and Gauss-Newton in ln x); otherwise the
        # fixed-point passes above.
        comp = cfg.composition or ({cfg.species[0]: 1.0} if len(cfg.species) == 1 else None)

        def solve_line(kk, idx, a, b):
            return inv.invert_on_mixing_line(
                self.model, self.table, kk, r2[:, idx], b2[:, idx], s2[idx],
                netd_K=self._inv_kw["netd_K"], composition=comp,
                num_threads=cfg.num_threads, progress=stage(a, b, "columns"))

        solve = solve_line if comp is not None else solve_passes

        # 1. The mixing line's slope: the scene parameter k that minimises the
        # total chi2 of a sample of the detected pixel-frames (<= 3000, contrast
        # >= 10x noise) solved on the line (a profile likelihood over a 10 K
        # grid of k, refined by a parabola; engine: qogi.inversion.
        # mixing_line_slope). Pixel-by-pixel free temperatures are too weakly
        # determined (and two-branched) to average into k. Without a known
        # composition the engine chooses the sample and reads k off the
        # profile; the fixed-point passes above solve it on the line.
        netd_K = self._inv_kw["netd_K"]
        if comp is not None:
            found = inv.mixing_line_slope(self.model, self.table, r2, b2, s2, netd_K=netd_K,
                                          composition=comp, num_threads=cfg.num_threads,
                                          progress=stage(0.0, 0.3, "mixing line"))
        else:
            cand, _ = inv.mixing_line_slope_sample(self.model, self.table, r2, b2, netd_K=netd_K)
            found = None
            if cand.size >= 5:
                grid = np.arange(lo - t_amb, hi - t_amb + 1e-9, 10.0)
                chi = [solve(float(kk), cand, 0.3 * i / grid.size, 0.3 * (i + 1) / grid.size).chi2
                       for i, kk in enumerate(grid)]
                found = inv.mixing_line_slope_from_profile(grid, np.asarray(chi))
        self.k_K_per_fraction, self.k_sigma, self.mixing_pixels = 0.0, 0.0, 0
        if found is not None:
            self.mixing_pixels = found.num_samples
            if found.found:
                self.k_K_per_fraction = found.slope_K_per_fraction
                self.k_sigma = found.sigma_K_per_fraction
        k = self.k_K_per_fraction
        self._set_proxy_lookup(k)

        # What needs the final lookup (the proxy field's conversion) runs on a
        # worker thread alongside the per-pixel solve.
        job, failure = None, []
        if alongside is not None:
            self.proxy_nodes  # made here, before the worker uses it

            def work() -> None:
                try:
                    alongside()
                except BaseException as e:  # re-raised below
                    failure.append(e)

            job = _workers().start(work, "qogi-proxy")
        try:
            everything = np.arange(nt * n)
            flat = solve(k, everything, 0.3, 0.9)
        finally:
            if job is not None:
                job.join()
        if failure:
            raise failure[0]
        # Sensitivity to k on every 5th frame: carried into the column term.
        self.k_relative_effect = 0.0
        if self.k_sigma > 0:
            sub = (np.arange(0, nt, 5)[:, None] * n + np.arange(n)[None, :]).ravel()
            base = sum(flat.column_density[sp][sub].sum() for sp in cfg.species)
            alt = solve(k + self.k_sigma, sub, 0.9, 1.0)
            other = sum(alt.column_density[sp].sum() for sp in cfg.species)
            if base > 0:
                self.k_relative_effect = float(abs(other - base) / base)
        res_cols = {sp: flat.column_density[sp].reshape(nt, n) for sp in cfg.species}
        res_sig = {sp: flat.column_density_sigma[sp].reshape(nt, n) for sp in cfg.species}
        ok = (flat.valid | (flat.status == inv.BELOW_DETECTION)).reshape(nt, n)
        out = []
        for j in range(n_surfaces):
            a, b = edges[j], edges[j + 1]
            cols = {sp: np.where(ok[:, a:b], res_cols[sp][:, a:b], np.nan) for sp in cfg.species}
            sigs = {sp: np.where(ok[:, a:b], res_sig[sp][:, a:b], 0.0) for sp in cfg.species}
            out.append((cols, sigs))
        return out, flat.counts()

    def _invert(self, rad, bg, sigma_pixels, sigma_param, noise_scale, progress):
        """One inversion call; with an inferred temperature and no given depth,
        a Gaussian prior on sigma centred on each pixel's width estimate."""
        inv = self.inv_module
        if sigma_param is None:
            # The prior's centre varies per surface: group the pixels by it.
            out = None
            res_all = {}
            for val in np.unique(sigma_pixels):
                sel = sigma_pixels == val
                inversion = inv.Inversion(self.model, self.scene.ambient_K,
                                          sigma_m=inv.prior(float(val), 0.5 * float(val),
                                                            1e-3, 0.5), table=self.table,
                                          **self._inv_kw)
                res_all[float(val)] = (sel, inversion.invert(rad, background_radiance=bg,
                                                             mask=sel, progress=progress))
            # Merge: each pixel from the run that selected it.
            sels = list(res_all.values())
            out = sels[0][1]
            for sel, r in sels[1:]:
                out = _merge_results(out, r, sel)
            return out
        inversion = inv.Inversion(self.model, self.scene.ambient_K, sigma_m=sigma_param,
                                  table=self.table, **self._inv_kw)
        if noise_scale != 1.0:
            return inversion.invert_mean(rad[None] if rad.ndim == 2 else rad,
                                         background_radiance=bg, sigma_m=sigma_pixels,
                                         progress=progress)
        return inversion.invert(rad, background_radiance=bg, sigma_m=sigma_pixels,
                                progress=progress)


@dataclasses.dataclass
class _RunState:
    """What every block of a run shares (set up once by :func:`_run`)."""

    rec: Recording
    cfg: QuantifyConfig
    scene: _Scene
    surfaces: List[Surface]
    samples: list
    roi: Region
    horizontal: bool
    source: Optional[Tuple[float, float]]
    transport: Optional[tuple]
    crop: Tuple[slice, slice]
    columns: object
    timebase: object
    start: int
    keep_maps: bool
    map_every: int
    radiance_check: object


@dataclasses.dataclass
class _BlockOut:
    """The kept frames of one block: per surface {species:
    :class:`_SurfaceFlux`}, the pixel status counts, kept maps and the
    velocimetry's notes (per-frame sums only: a run's memory does not grow
    with the pixels of its surfaces times its frames)."""

    flux: list
    n: int
    counts: Dict[str, int]
    maps: Dict[int, dict]
    velocity_info: Dict[str, object]
    cancelled: bool = False


@dataclasses.dataclass
class _SurfaceFlux:
    """One surface's and species' flux over some frames: ``rate`` [kg/s] per
    frame (NaN without a valid column), ``pixels`` used per frame, and the
    sum over frames and pixels of (v_n sigma_c dl)^2 [(kg/s)^2] (the
    columns' random term)."""

    rate: np.ndarray
    pixels: np.ndarray
    column_variance: float
    #: For the detection limit (qogi.detection), summable over blocks: the
    #: column-weighted |v_n| sums, each frame's median |v_n| and effective
    #: plume width [m] (NaN without gas).
    cv_sum: float = 0.0
    c_sum: float = 0.0
    vabs_median: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    width_m: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    #: The budget checks' sums (:class:`qogi.flux_summary.FluxSummary`).
    summary: object = None


def _surface_flux(c: np.ndarray, sig: np.ndarray, vn: np.ndarray, dl: np.ndarray,
                  speed_floor: float = 0.0) -> _SurfaceFlux:
    """Thesis eq. 12 per frame: sum over the samples of column c [kg/m2] x
    normal velocity vn [m/s] x length dl [m], (frames, samples) arrays;
    ``speed_floor`` [m/s] the direction check's least speed."""
    from .detection import frame_widths, velocity_sums
    from .flux_summary import FluxSummary
    good = np.isfinite(c)
    with np.errstate(invalid="ignore"):
        flux = np.where(good, c, 0.0) * vn * dl[None, :]
    rate = flux.sum(axis=1)
    rate[~good.any(axis=1)] = np.nan
    vsig = np.where(np.isfinite(vn), vn, 0.0) * sig * dl[None, :]
    cv, cs, vmed = velocity_sums(c, np.broadcast_to(vn, c.shape))
    return _SurfaceFlux(rate, good.sum(axis=1), float(np.sum(vsig ** 2)), cv, cs, vmed,
                        frame_widths(c, dl), FluxSummary.of(c, sig, vn, dl, speed_floor))


#: Frames per block (the pipeline's memory bound) when not configured: the
#: block's float32 fields (column field, flow, frame velocities, their
#: normalised copy, ~8 per frame) within this many bytes.
BLOCK_BYTES = 1 << 30
#: Frames per block at least (the transport's flux level is a time average
#: over the block: at 15 Hz, 30 s).
MIN_BLOCK_FRAMES = 450


def _block_frames(cfg: QuantifyConfig, rec: Recording) -> int:
    if cfg.block_frames is not None:
        return cfg.block_frames
    per_frame = 8 * 4 * rec.height * rec.width
    return int(max(MIN_BLOCK_FRAMES, BLOCK_BYTES // per_frame))


def _run(rec: Recording, surfaces: List[Surface], cfg: QuantifyConfig, progress, keep_maps):
    from . import checks
    from .diagnostics import Diagnostics
    from .timebase import frame_timebase, stream_blocks

    t_start = time.perf_counter()

    def say(fraction: float, message: str) -> None:
        if progress is not None and progress(min(1.0, max(0.0, fraction)), message) is False:
            raise Cancelled("quantification cancelled")

    scene = _Scene(rec, cfg)
    start, stop = cfg.frames or (0, rec.n_frames)
    frames = range(start, stop)
    nf = len(frames)
    warnings = Diagnostics()
    checks.check_frame_count(nf, cfg.velocity, warnings)
    tb = frame_timebase(np.asarray(rec.time_s)[start:stop], scene.frame_rate)
    checks.report_timebase(tb, start, warnings)
    h, w = rec.height, rec.width
    checks.check_source(cfg.source, w, h, surfaces, warnings)
    # The velocity field is computed over the whole frame: the flow solvers
    # need room around the surfaces (a crop through the plume is an open
    # boundary they cannot see across).
    roi = Region(0, 0, w, h)
    horizontal = all(abs(np.diff(np.asarray(s.points)[:, 0])).sum() >=
                     abs(np.diff(np.asarray(s.points)[:, 1])).sum() for s in surfaces)
    samples = []
    for s in surfaces:
        xy, n, dl = s.samples(step_px=1.0)
        t = np.concatenate([[0.0], np.cumsum(dl)])[:-1] + 0.5 * dl
        samples.append((xy, n, dl * scene.pixel_m, t / s.length_px))

    radiance_check = checks.RadianceCheck(rec.channels)
    t_bg_guess = rec.scene.background_temperature_K
    if t_bg_guess is None:
        first = rec.frame(start, quantity="radiometric_temperature")
        t_bg_guess = float(np.nanmedian(first))
    channel_sign = np.full(rec.n_channels, 1.0 if scene.gas_K >= t_bg_guess else -1.0)
    # Up to 50 frames spread over the run: the background's choice and static
    # shape and, without a given source, the plume's source for the flux
    # level of the default velocimetry (the surfaces keep their own
    # orientation).
    velocity_info: Dict[str, object] = {}
    source = cfg.source
    if source is not None:
        velocity_info["source_xy"] = [float(source[0]), float(source[1])]
    want_source = (source is None and cfg.velocity == "fluid" and cfg.flux_level and
                   cfg.column_density != "truth")
    sample_frames = None
    if want_source or (not isinstance(cfg.background, Region) and
                       cfg.background != "percentile"):
        sample = list(frames)[::max(1, len(frames) // 50)][:50]
        sample_frames = np.asarray([rec.frame(f, quantity="radiance") for f in sample],
                                   dtype=np.float64)
        for f, fr in zip(sample, sample_frames):
            radiance_check(fr[None].astype(np.float32), f)
    bg_cfg, velocity_info["background_choice"] = _choose_background(cfg, sample_frames, surfaces,
                                                                    samples, channel_sign)
    background = _Background(rec, bg_cfg, roi, frames, channel_sign, say, t_bg_guess)
    if not isinstance(bg_cfg.background, Region) and bg_cfg.background != "percentile":
        sl = roi.slices()
        background.set_static_shape(sample_frames[:, :, sl[0], sl[1]].mean(axis=0))
    if want_source and len(sample_frames) >= 2:
        from .surfaces import _plume_image, detect_source
        try:
            source = detect_source(_plume_image(sample_frames))
            velocity_info["source_xy"] = [float(source[0]), float(source[1])]
            velocity_info["source"] = (f"detected at x={source[0]:.1f}, y={source[1]:.1f} "
                                       f"(for the flux level; give source= to set it)")
        except ValueError as e:
            velocity_info["source"] = f"not detected: {e}"
    del sample_frames
    radiance_check.bad_pixels = radiance_check.total_pixels = 0  # counted again per block
    radiance_check.first_frame = None

    if cfg.column_density == "truth":
        columns = _TruthColumns(rec, cfg)
    else:
        say(0.01, "cross-section tables and the scene's inversion table")
        columns = _InvertedColumns(rec, cfg, scene, roi, horizontal, background)

    # The flow's part of the region (all of it without a source).
    transport = None
    crop = (slice(0, h), slice(0, w))
    if source is not None and cfg.velocity not in ("wind", "exit"):
        transport = _transport_crop(surfaces, source, roi, (h, w))
        crop = transport[2]
    state = _RunState(rec, cfg, scene, surfaces, samples, roi, horizontal, source, transport,
                      crop, columns, tb, start, keep_maps, max(1, nf // 10), radiance_check)
    # Stream the run in blocks (bounded memory), cut at gaps in time_s.
    blocks = stream_blocks(tb.segments, _block_frames(cfg, rec), overlap=4)
    outs: List[_BlockOut] = []
    for i, blk in enumerate(blocks):
        label = f" (block {i + 1}/{len(blocks)})" if len(blocks) > 1 else ""

        def say_block(fraction: float, message: str, i=i, label=label) -> None:
            say((i + fraction) / len(blocks), message + label)

        try:
            out = _analyse_block(state, blk, say_block)
        except Cancelled:
            out = None
        if out is not None:
            outs.append(out)
        if out is None or out.cancelled:
            radiance_check.report(warnings)
            raise Cancelled("quantification cancelled", partial=_finish(
                state, outs, velocity_info, t_start, warnings, complete=False)) from None
    radiance_check.report(warnings)
    return _finish(state, outs, velocity_info, t_start, warnings, complete=True)


def _analyse_block(st: _RunState, blk, say) -> _BlockOut:
    """Columns, velocity and the normal velocity on the surfaces of the
    frames of one block (``blk``, a :class:`qogi.timebase.Block`)."""
    rec, cfg, roi, samples, columns = st.rec, st.cfg, st.roi, st.samples, st.columns
    a, b = blk.read
    nb = b - a
    first = st.start + a
    col_fields = np.zeros((nb, roi.y1 - roi.y0, roi.x1 - roi.x0), dtype=np.float32)
    surf_cols = [{sp: np.full((nb, len(x[0])), np.nan) for sp in cfg.species} for x in samples]
    surf_sig = [{sp: np.zeros((nb, len(x[0]))) for sp in cfg.species} for x in samples]
    counts: Dict[str, int] = {}
    velocity_info: Dict[str, object] = {}
    done = 0
    if hasattr(columns, "start_block"):
        columns.start_block()

    def invert_collected(n_done: int, time_averaged: bool, alongside=None) -> None:
        if cfg.column_density == "truth" or n_done == 0:
            return
        per_surface, cnt = columns.finish(
            samples, time_averaged=time_averaged,
            progress=lambda fr_: say(0.35 + 0.25 * fr_, "inverting the surfaces' pixels"),
            alongside=alongside)
        for j in range(len(samples)):
            for sp in cfg.species:
                surf_cols[j][sp][:n_done] = per_surface[j][0][sp]
                surf_sig[j][sp][:n_done] = per_surface[j][1][sp]
        for key, v in cnt.items():
            counts[key] = counts.get(key, 0) + int(v)

    def kept(vn, cancelled=False, n_done=nb, flows=None) -> _BlockOut:
        # A cancelled block has no velocity: zero there (its rates are the
        # columns' only; the partial result says so with complete=False).
        k0 = blk.offset
        k1 = max(k0, min(k0 + blk.n_keep, n_done))
        flux = []
        for j, (xy, n, dl, t) in enumerate(samples):
            v = np.zeros((k1 - k0, len(xy))) if vn is None else vn[j][k0:k1]
            flux.append({sp: _surface_flux(surf_cols[j][sp][k0:k1], surf_sig[j][sp][k0:k1], v,
                                           dl, _speed_floor(st, flows, j, sp))
                         for sp in cfg.species})
        return _BlockOut(flux, k1 - k0, counts, {}, velocity_info, cancelled)

    time_averaged = cfg.averaging == "time-averaged"
    try:
        if cfg.column_density == "truth":
            for k in range(nb):
                fields = columns.frame(first + k, roi)
                if time_averaged:
                    acc = fields if k == 0 else {sp: acc[sp] + fields[sp] for sp in fields}
                col_fields[k] = sum(fields.values())
                for j, (xy, n, dl, t) in enumerate(samples):
                    for sp in cfg.species:
                        surf_cols[j][sp][k] = _bilinear(fields[sp], xy - [roi.x0, roi.y0])
                counts["converged"] = counts.get("converged", 0) + \
                    sum(len(x[0]) for x in samples)
                done = k + 1
                say(0.05 + 0.3 * done / nb, f"column field, frame {done}/{nb}")
        else:
            # Sub-blocks of frames: one read and one vectorised pass each (at
            # least ten, for the progress and a cancel's partial result).
            sub = int(np.clip(nb // 10, 1, 25))
            for k in range(0, nb, sub):
                m = min(sub, nb - k)
                fr = rec.frames(first + k, first + k + m, quantity="radiance")
                st.radiance_check(fr, first + k)
                columns.collect(fr, st.surfaces, samples, out=col_fields[k:k + m])
                done = k + m
                say(0.05 + 0.3 * done / nb, f"background and column field, frame {done}/{nb}")
        if time_averaged and cfg.column_density == "truth":
            for j, (xy, n, dl, t) in enumerate(samples):
                for sp in cfg.species:
                    surf_cols[j][sp][:] = _bilinear(acc[sp] / nb, xy - [roi.x0, roi.y0])
        # The proxy field over the whole region (the flow runs on its part,
        # crop; the flux level's transport balance on all of it) is turned
        # into a column alongside the surfaces' final solve.
        part = col_fields[:done]
        invert_collected(done, time_averaged, alongside=lambda: columns.contrast_to_column(part))
        if cfg.column_density != "truth":
            velocity_info["proxy_anchor"] = _anchor_proxy(
                part, samples, surf_cols, cfg.species[0], st.horizontal, roi)
    except Cancelled:
        try:
            invert_collected(done, time_averaged)
        except Cancelled:
            pass
        return kept(None, cancelled=True, n_done=done)

    intervals = st.timebase.pair_intervals[a:b - 1]
    flows = _block_velocity(st, col_fields, intervals, velocity_info, say)
    vn = [_normal_velocity(st, flows, xy, n, nb) for (xy, n, dl, t) in samples]
    out = kept(vn, flows=flows)
    if st.keep_maps and flows is not None:
        # Maps (every tenth of the run) keyed by the recording's frame index,
        # the velocity back in the whole region.
        fu, fv, (cx, cy) = flows
        for k in range(blk.offset, blk.offset + blk.n_keep):
            if (a + k) % st.map_every:
                continue
            uv = tuple(np.zeros(col_fields.shape[1:], np.float32) for _ in range(2))
            for full, p in zip(uv, (fu[k], fv[k])):
                full[cy:cy + p.shape[0], cx:cx + p.shape[1]] = p
            out.maps[first + k] = {"column_density_kg_m2": {cfg.species[0]: col_fields[k].copy()},
                                   "velocity_px_per_frame": uv, "origin": (roi.x0, roi.y0)}
    return out


def _normal_velocity(st: _RunState, flows, xy: np.ndarray, n: np.ndarray, nb: int) -> np.ndarray:
    """The velocity along each sample's normal [m/s], (frames, samples):
    the given speed, or the flow's (px per nominal frame interval) sampled
    at the surface (zero outside the flow's part; NaN without a flow)."""
    cfg, roi = st.cfg, st.roi
    if cfg.velocity == "wind":
        return np.full((nb, len(xy)), float(cfg.wind_speed_m_s))
    if cfg.velocity == "exit":
        return np.full((nb, len(xy)), float(cfg.exit_velocity_m_s))
    if flows is None:
        return np.full((nb, len(xy)), np.nan)
    fu, fv, (cx, cy) = flows
    p = xy - [roi.x0 + cx, roi.y0 + cy]
    h, w = fu.shape[1:]
    inside = (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)
    u = _bilinear(fu, p)
    v = _bilinear(fv, p)
    return np.where(inside, (u * n[:, 0] + v * n[:, 1]) * st.scene.m_s_per_px_frame, 0.0)


def _pair_durations(intervals: np.ndarray, stride: int, n_frames: int) -> np.ndarray:
    """Duration [nominal frame intervals] of the pairs of frames 0, stride,
    2 stride, ... of a block whose consecutive frames are ``intervals`` apart."""
    t = np.concatenate([[0.0], np.cumsum(intervals)])[:n_frames]
    return np.diff(t[::stride])


def _block_velocity(st: _RunState, col_fields: np.ndarray, intervals: np.ndarray,
                    velocity_info: Dict[str, object], say):
    """The velocity at every frame of a block [px per nominal frame
    interval] over the flow's part of the region: (u, v, (x0, y0)), or None
    (given speeds; fewer than 2 frames)."""
    from . import velocimetry as vel

    cfg, roi, crop, source = st.cfg, st.roi, st.crop, st.source
    done = col_fields.shape[0]
    if cfg.velocity in ("wind", "exit") or done < 2:
        return None
    # Every frame's field (also for the time-averaged order: the gas
    # moves, the averaged field does not).
    velocity_frames = col_fields
    source_mask = None
    if source is not None:
        sx, sy = source[0] - roi.x0, source[1] - roi.y0
        yy, xx = np.mgrid[0:velocity_frames.shape[1], 0:velocity_frames.shape[2]]
        rad = 6.0
        source_mask = ((xx - sx) ** 2 + (yy - sy) ** 2) <= rad ** 2
        if not source_mask.any():
            source_mask = None
    # With the fluid method and a known source, the flux level comes from
    # the transport of the line-integrated column (time of flight of the
    # plume's structures: mass conservation alone cannot fix it in a
    # steady plume; docs/velocimetry.md).
    flux_note = "off: " + ("a method other than fluid" if cfg.velocity != "fluid" else
                           "flux_level=False" if not cfg.flux_level else
                           "no source given or detected" if source is None else
                           "fewer than 3 frames" if done < 3 else "")
    if flux_note == "off: ":
        axis, index, _, region_index = st.transport
    field = velocity_frames[:, crop[0], crop[1]]
    mask = source_mask[crop[0], crop[1]] if source_mask is not None else None
    # The flows' scale: the 99.5th percentile of (up to) 100 frames spread
    # over the block.
    scale = np.percentile(field[::max(1, field.shape[0] // 100)], 99.5)
    norm = np.ascontiguousarray(field / scale if scale > 0 else field, dtype=np.float32)
    # The flux level's transport along the whole region (the plume's
    # structures beyond the flow's part constrain it too;
    # docs/velocimetry.md), on a worker thread while the flow runs.
    transport_result: list = []
    job = None
    if flux_note == "off: ":
        def measure() -> None:
            try:
                transport_result.append(vel.transport_flux(velocity_frames, axis, region_index,
                                                           intervals=intervals))
            except BaseException as e:  # reported as the level's note below
                transport_result.append(e)

        job = _workers().start(measure, "qogi-transport")
    # Pairs `stride` frames apart where the plume moves little per frame
    # (at 100 Hz a lab plume crosses ~1 px per frame): ~3 px per pair, at
    # most every 4th frame, with the transport's flux level (which sets
    # the level; the flow gives the pattern: the same rates to 0.1 % on
    # the lab releases at strides 1-4, docs/velocimetry.md).
    stride = cfg.pair_stride
    if stride is None:
        stride = 1
        if flux_note == "off: ":
            d = vel.typical_displacement(field, axis)
            if np.isfinite(d) and d > 0:
                stride = int(np.clip(round(3.0 / d), 1, 4))
    stride = max(1, min(int(stride), (norm.shape[0] - 1) // 2))
    velocity_info["pair_stride"] = stride
    fvel = None
    try:
        seq = vel.optical_flow_sequence(
            norm[::stride], method=cfg.velocity, source_mask=mask, warm_start=True,
            workers=0, progress=lambda fr_: say(0.6 + 0.3 * fr_, "velocimetry"))
        # Each pair's displacement over its real duration (time_s), in px per
        # `stride` nominal frame intervals.
        per = (stride / _pair_durations(intervals, stride, done)).astype(np.float32)
        if not np.all(per == 1.0):
            seq.u *= per[:, None, None]
            seq.v *= per[:, None, None]
        if stride > 1:
            fvel = vel.interpolate_frame_velocity(*vel.frame_velocity(seq), stride,
                                                  norm.shape[0])
    except KeyboardInterrupt:
        raise Cancelled("quantification cancelled", partial=None) from None
    finally:
        if job is not None:
            job.join()
    uv = None
    if flux_note == "off: ":
        try:
            tf = transport_result[0]
            if isinstance(tf, BaseException):
                raise tf
            # In the flow field's units and lines.
            lines = crop[0] if axis in ("up", "down") else crop[1]
            tf = tf.lines(lines, scale=1.0 / scale if scale > 0 else 1.0)
            u, v, level = vel.calibrate_flux_level(seq, norm, axis, index, transport=tf,
                                                   frame_velocities=fvel)
            uv = (u, v)
            flux_note = (f"on: transport of the line-integrated column, axis {axis}"
                         if np.isfinite(level).any() else
                         f"on: transport velocity of each line along axis {axis} (the "
                         f"flow did not follow the transport, e.g. wind faster than it "
                         f"can track)")
        except ValueError as e:
            flux_note = f"off: {e}"
    if uv is None:
        uv = fvel if fvel is not None else vel.frame_velocity(seq)
    velocity_info["flux_level"] = flux_note
    # The analysed part and its origin in the region (no velocity outside it).
    return (uv[0], uv[1], (crop[1].start, crop[0].start))


def _choose_background(cfg: QuantifyConfig, sample_frames, surfaces, samples, channel_sign):
    """The background method of the run: ``"auto"`` chooses between beside
    the surfaces and the temporal percentile from the scene
    (:func:`qogi.background.choose`). Returns (the config the background
    stage uses, the choice's record for ``info``, or None)."""
    if cfg.background != "auto":
        return cfg, None
    from .background import choose

    if sample_frames is None or len(sample_frames) < 2:
        # No frame-to-frame noise to test the strips with: the strips beside
        # the surfaces (the estimate that needs no time series).
        return dataclasses.replace(cfg, background="beside-surface"), {
            "method": "beside-surface", "reason": "fewer than 2 frames: the strips not tested",
            "strips": [], "relative": {}, "not_gas_free": []}
    choice = choose(sample_frames, surfaces, samples, channel_sign, cfg.background_percentile)
    return dataclasses.replace(cfg, background=choice["method"]), choice


def _transport_crop(surfaces, source, roi: Region, shape: Tuple[int, int]):
    """The plume's axis in the image (``up``, ``down``, ``left``, ``right``:
    from the source towards the surfaces), the source's line along it in the
    part of the region the flow uses (index), that part: up to a margin
    beyond the farthest surface (the gas leaving through the cut is the flow
    balance's outflow), and the source's line in the whole region (for the
    transport flux level, measured along all of it). Returns (axis, index,
    (row slice, column slice), region_index)."""
    pts = np.concatenate([np.asarray(s.points, float) for s in surfaces])
    dx, dy = pts.mean(axis=0) - np.asarray(source)
    if abs(dy) >= abs(dx):
        axis, index = ("up" if dy < 0 else "down"), source[1] - roi.y0
        coord, size = pts[:, 1] - roi.y0, shape[0]
    else:
        axis, index = ("right" if dx > 0 else "left"), source[0] - roi.x0
        coord, size = pts[:, 0] - roi.x0, shape[1]
    far = coord.min() if axis in ("up", "left") else coord.max()
    region_index = index
    margin = max(48.0, abs(index - far))
    if axis in ("up", "left"):
        cut = slice(int(min(size - 1, max(0, np.floor(far - margin)))), size)
        index -= cut.start
    else:
        cut = slice(0, int(max(1, min(size, np.ceil(far + margin) + 1))))
    crop = (cut, slice(0, shape[1])) if axis in ("up", "down") else (slice(0, shape[0]), cut)
    return axis, index, crop, region_index


def _anchor_proxy(fields: np.ndarray, samples, surf_cols, species: str, horizontal: bool,
                  roi: Region) -> Dict[str, float]:
    """Scales the velocity proxy (T, H, W) line by line to the inverted
    columns where both exist: along each surface, the ratio of the full
    inversion's column sum to the proxy's (over every frame) is the proxy's
    calibration there; lines between surfaces take it interpolated, lines
    beyond the outermost surfaces the nearest one's. The velocimetry's mass
    balance needs the proxy proportional to the column along the plume, which
    a single-channel lookup cannot promise where the gas cools and thins.
    Returns {line: ratio} of the anchors (for the record)."""
    pos, ratio = [], []
    for (xy, n, dl, t), cols in zip(samples, surf_cols):
        inv = cols[species][:fields.shape[0]]
        good = np.isfinite(inv)
        if not good.any():
            continue
        prox = np.stack([_bilinear(fields[k], xy - [roi.x0, roi.y0])
                         for k in range(fields.shape[0])])
        a, b = float(np.sum(np.where(good, inv, 0.0))), float(np.sum(np.where(good, prox, 0.0)))
        if a > 0 and b > 0:
            pos.append(float(np.mean(xy[:, 1] - roi.y0 if horizontal else xy[:, 0] - roi.x0)))
            ratio.append(a / b)
    if not pos:
        return {}
    order = np.argsort(pos)
    pos, ratio = np.asarray(pos)[order], np.asarray(ratio)[order]
    view = fields if horizontal else fields.transpose(0, 2, 1)
    lines = np.arange(view.shape[1])
    scale = np.exp(np.interp(lines, pos, np.log(ratio))).astype(np.float32)
    view *= scale[None, :, None]
    return {f"{p:.0f}": float(r) for p, r in zip(pos, ratio)}


def _finish(st: _RunState, outs: List["_BlockOut"], velocity_info, t_start, warnings,
            complete: bool) -> Result:
    """The Result of the blocks analysed (in order): each surface's and
    species' per-frame rates, their mean and 90 % interval."""
    from . import _engine
    from . import checks

    rec, cfg, scene, surfaces, columns = st.rec, st.cfg, st.scene, st.surfaces, st.columns
    done = sum(o.n for o in outs)
    times = st.timebase.time_s[:done]
    status_counts: Dict[str, int] = {}
    kept_maps: Dict[int, dict] = {}
    for o in outs:
        for key, v in o.counts.items():
            status_counts[key] = status_counts.get(key, 0) + int(v)
        kept_maps.update(o.maps)
    if outs:
        # The notes of the longest block (the first of equals).
        longest = outs[int(np.argmax([o.n for o in outs]))]
        velocity_info = {**velocity_info, **longest.velocity_info}
        if len(outs) > 1:
            velocity_info["blocks"] = len(outs)
            notes = sorted({str(o.velocity_info.get("flux_level")) for o in outs
                            if "flux_level" in o.velocity_info})
            if len(notes) > 1:
                velocity_info["flux_level"] = "; ".join(notes)
    vsys = cfg.velocity_systematic if cfg.velocity_systematic is not None else \
        VELOCITY_SYSTEMATIC[cfg.velocity]
    # Too short a run for the velocimetry: its level is not measured.
    few = cfg.velocity not in ("wind", "exit") and done < checks.MIN_FRAMES_RATE
    if few:
        vsys = max(vsys, 1.0)
    # The inferred temperature's mixing-line slope and its effect on the columns.
    mixing = {}
    col_sys = cfg.column_systematic
    if col_sys is None:
        col_sys = COLUMN_SYSTEMATIC_INFERRED if cfg.gas_temperature == "infer" else \
            COLUMN_SYSTEMATIC
    if columns is not None and getattr(columns, "k_K_per_fraction", None) is not None:
        mixing = {"mixing_line_K_per_fraction": columns.k_K_per_fraction,
                  "mixing_line_sigma_K_per_fraction": columns.k_sigma,
                  "mixing_line_pixels": columns.mixing_pixels,
                  "mixing_line_column_effect": columns.k_relative_effect}
        col_sys = math.hypot(col_sys, columns.k_relative_effect)
    results = []
    from .flux_summary import FluxSummary
    advice: Dict[str, list] = {sp: [] for sp in cfg.species}
    flux_inputs: Dict[tuple, FluxSummary] = {}
    bg_choice = (velocity_info or {}).get("background_choice")
    rise_speeds: Dict[int, float] = {}
    for j, (s, (xy, n, dl, t)) in enumerate(zip(surfaces, st.samples)):
        per_species = {}
        for sp in cfg.species:
            parts = [o.flux[j][sp] for o in outs]
            rate = np.concatenate([p.rate for p in parts]) if parts else np.zeros(0)
            pixels = np.concatenate([p.pixels for p in parts]) if parts else np.zeros(0, int)
            mean = float(np.nanmean(rate)) if np.isfinite(rate).any() else float("nan")
            finite = rate[np.isfinite(rate)]
            n_eff = _effective_samples(finite) if finite.size else 0.0
            sd = float(np.std(finite, ddof=1)) if finite.size > 1 else 0.0
            temporal = sd / math.sqrt(n_eff) if n_eff > 0 else 0.0
            col_rand = math.sqrt(sum(p.column_variance for p in parts)) / max(1, finite.size)
            summary = FluxSummary.empty(len(xy))
            for p in parts:
                if p.summary is not None:
                    summary += p.summary
            terms = {
                "temporal": temporal * 3600,
                "velocity": abs(mean) * vsys * 3600,
                "column density": math.sqrt(col_rand ** 2 + (abs(mean) * col_sys) ** 2)
                * 3600,
                "line shape": abs(mean) * _line_shape_term(columns, j, sp, summary,
                                                           warnings, s.name) * 3600,
            }
            if bg_choice is not None and cfg.column_density != "truth":
                terms["background"] = abs(mean) * bg_choice["relative"].get(j, 0.0) * 3600
            sigma = math.sqrt(sum(v * v for v in terms.values()))
            mean_h = mean * 3600
            ci = (mean_h - 1.645 * sigma, mean_h + 1.645 * sigma)
            ci = _check_direction(summary, mean, ci, warnings, s.name, sp)
            if finite.size:
                advice[sp].append(_record_advice(finite, n_eff, summary, dl, columns, j, scene))
            flux_inputs[(j, sp)] = summary
            if sp == cfg.species[0]:
                if summary.mass_line > 0 and finite.size:
                    rise_speeds[j] = float(np.sum(finite)) / summary.mass_line * \
                        (done / finite.size)
            dominant = max(terms, key=terms.get)
            limit, det = None, None
            if hasattr(columns, "model"):  # the inversion's forward model (not truth columns)
                from .detection import velocity_from_sums, detection_limit_from_sums
                v_n = velocity_from_sums(sum(p.cv_sum for p in parts),
                                          sum(p.c_sum for p in parts),
                                          np.concatenate([np.zeros(0)] +
                                                         [p.vabs_median for p in parts]))
                limit, det = detection_limit_from_sums(
                    columns.model, sp, rec.camera.netd_K or 0.02, columns._bg_t, scene.gas_K,
                    scene.ambient_K, v_n,
                    np.concatenate([np.zeros(0)] + [p.width_m for p in parts]), dl,
                    mean_snr=columns.mean_contrast_snr(j))
            truth = None
            if rec.truth is not None and sp in rec.truth.emission_rate_kg_s:
                truth = rec.truth.emission_rate_kg_s[sp] * 3600
            per_species[sp] = SpeciesRate(
                species=sp, time_s=times, rate_kg_s=rate, mean_kg_h=mean_h, ci90_kg_h=ci,
                n_frames=int(finite.size), molar_mass_kg_mol=_engine.molar_mass(sp),
                uncertainty_terms_kg_h=terms, dominant_uncertainty=dominant, pixels_used=pixels,
                truth_kg_h=truth, detection_limit_kg_h=limit, detection=det)
        results.append(SurfaceResult(s, per_species))
    info = {"seconds": time.perf_counter() - t_start, "frames": int(done),
            "frame_rate_hz": float(scene.frame_rate), "pixel_m": float(scene.pixel_m),
            "gas_temperature_K": float(scene.gas_K), "velocity_systematic": float(vsys),
            "column_systematic": float(col_sys), **mixing, **(velocity_info or {})}
    _record_warnings(advice, info, warnings)
    if bg_choice is not None and cfg.column_density != "truth":
        for name, excess in bg_choice.get("not_gas_free", []):
            warnings.add("background-not-gas-free",
                         f"neither background is gas-free here: the strips beside the surface "
                         f"carry gas and the temporal percentile along it stands {excess:.0f} "
                         f"noise above the line between its ends (gas that never leaves); the "
                         f"columns are low by about that, carried in the budget's background "
                         f"term; draw longer surfaces or give a gas-free background region",
                         surface=name, excess_noise=excess)
    if complete and columns is not None and cfg.column_density != "truth":
        from .hotgas import check_gas_temperature
        check_gas_temperature(cfg, scene, results, columns, st.samples, flux_inputs, rise_speeds,
                              (velocity_info or {}).get("source_xy"), warnings, info)
    if not checks.check_result(results, warnings):
        complete = False
    return Result(results, config=cfg, recording_path=str(rec.path), pixel_status=status_counts,
                  maps=kept_maps, info=info, complete=complete, warnings=warnings)


def _line_shape_term(columns, j: int, species: str, summary, warnings, surface: str) -> float:
    """Relative ``line shape`` term of surface j (qogi.budget): the largest
    change of the flux when its columns are re-read through the other
    rules; 0 without an inversion (truth columns)."""
    if columns is None or not hasattr(columns, "line_shape_curves"):
        return 0.0
    try:
        grid, ratios = columns.line_shape_curves(j, species)
    except (ValueError, RuntimeError, OSError) as e:
        warnings.add("line-shape-term-missing", f"the line-shape term could not be sized: {e}",
                     surface=surface, species=species)
        return 0.0
    return max([abs(f - 1.0) for f in summary.flux_ratios(grid, ratios)], default=0.0)


def _speed_floor(st: "_RunState", flows, j: int, species: str) -> float:
    """The least speed [m/s] the direction check's flux bound assumes on
    surface j in a block: the flow's 90th-percentile speed and the buoyancy
    scale sqrt(g' width) (a plume moves at least about that fast where its own
    buoyancy drives it), so a dead flow cannot make the bound vanish."""
    from . import _engine

    scene = st.scene
    typical = 0.0
    if flows is not None:
        fu, fv, _ = flows
        if len(fu):
            step = max(1, len(fu) // 20)
            typical = float(np.nanpercentile(np.hypot(fu[::step], fv[::step]), 90)) \
                * scene.m_s_per_px_frame
    g_reduced = 9.81 * abs(1.0 - _engine.molar_mass(species) * scene.ambient_K /
                           (0.028965 * scene.gas_K))
    sigma_m = getattr(st.columns, "sigma_m", {}).get(j) or 0.02
    return max(typical, math.sqrt(g_reduced * 2.3548 * sigma_m))


def _check_direction(summary, mean_kg_s: float, ci, warnings, surface: str,
                     species: str) -> tuple:
    """The interval of a rate that runs against the surface's orientation or
    is zero while gas crosses it, widened to +-the flux the columns carry at
    the floored speed (:func:`_speed_floor`; docs/pipeline_api.md); with a
    warning ``flux-against-surface`` or ``zero-rate-with-gas``."""
    flag = summary.direction(mean_kg_s)
    if flag is None:
        return ci
    bound = flag["bound_kg_s"] * 3600
    lo, hi = min(ci[0], -bound), max(ci[1], bound)
    if flag["reason"] == "zero":
        warnings.add("zero-rate-with-gas",
                     f"the rate is zero while gas crosses the surface (no velocity there: e.g. "
                     f"a wrong source or flow direction); interval widened to "
                     f"[{lo:.4g}, {hi:.4g}] kg/h, the flux its columns carry at the flow's "
                     f"speed in either direction", surface=surface, species=species,
                     bound_kg_h=bound)
    else:
        warnings.add("flux-against-surface",
                     f"the rate runs against the surface's orientation (away from the source): "
                     f"the flux level or the source may be reversed; interval widened to "
                     f"[{lo:.4g}, {hi:.4g}] kg/h", surface=surface, species=species,
                     bound_kg_h=bound)
    return (lo, hi)


def _record_advice(finite, n_eff, summary, dl, columns, j, scene) -> dict:
    """qogi.budget.record_length_advice for one surface: the mean normal
    speed where gas is, and the plume's width (2.35 sigma of its depth)."""
    from .budget import record_length_advice

    sigma = (columns.sigma_m.get(j) if columns is not None and hasattr(columns, "sigma_m")
             else None) or float(np.sum(dl)) / 4.0
    return record_length_advice(finite, scene.frame_rate, n_eff, summary.mean_speed(),
                                2.3548 * sigma)


def _record_warnings(advice: Dict[str, list], info: dict, warnings) -> None:
    """The record length a 10 % mean needs (the longest over the surfaces):
    into ``info["record_length"]`` and, when the record is shorter, the
    warning ``record-too-short``."""
    out = {}
    for sp, items in advice.items():
        items = [a for a in items if np.isfinite(a["needed_s"])]
        if not items:
            continue
        worst = max(items, key=lambda a: a["needed_s"])
        out[sp] = {k: float(v) for k, v in worst.items()}
        if worst["needed_s"] > worst["record_s"]:
            warnings.add("record-too-short",
                         f"a 10 % (1 sigma) mean needs about {worst['needed_s']:.0f} s of record; "
                         f"this one is {worst['record_s']:.1f} s (temporal "
                         f"{100 * worst['temporal']:.0f} %, flux level "
                         f"{100 * worst['level']:.0f} % now)", species=sp,
                         needed_s=worst["needed_s"], record_s=worst["record_s"])
    if out:
        info["record_length"] = out
