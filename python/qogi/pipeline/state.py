"""The typed state a run passes from stage to stage.

:class:`RunState` is made once by :func:`qogi.pipeline.setup.prepare` and
filled in forward: the background stage sets :attr:`RunState.background`,
the columns stage :attr:`RunState.columns`, the velocity stage
:attr:`RunState.source` and :attr:`RunState.transport`; each block then
passes :class:`BlockColumns` -> :class:`Flow` -> :class:`BlockOut`, and the
budget stage turns :attr:`RunState.blocks` into the Result. Nothing here
imports a stage.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Callable, Dict, List, NamedTuple, Optional, Tuple

import numpy as np

from ..io.recording import Recording
from .config import QuantifyConfig
from .surfaces import Region, Surface

__all__ = [
    "Scene",
    "SurfaceSamples",
    "Transport",
    "FluxLevelPlan",
    "Flow",
    "RunState",
    "BlockColumns",
    "SurfaceFlux",
    "BlockOut",
]


class Scene:
    """Scene constants of a run (the recording's, overridden by the config)."""

    def __init__(self, rec: Recording, cfg: QuantifyConfig):
        sc = rec.scene
        self.distance_m = cfg.distance_m or sc.distance_m
        self.ambient_K = cfg.ambient_temperature_K or sc.ambient_temperature_K
        self.pressure_Pa = cfg.pressure_Pa or sc.pressure_Pa
        self.ifov = rec.camera.ifov_rad
        # A Recording always has a frame rate: opening checks /camera frame_rate_hz and
        # from_array takes it from time_s when not given.
        assert rec.camera.frame_rate_hz is not None
        self.frame_rate: float = rec.camera.frame_rate_hz
        self.pixel_m = self.distance_m * self.ifov
        self.m_s_per_px_frame = self.pixel_m * self.frame_rate
        self.netd = rec.camera.netd_K or 0.02
        self.gas_K = (
            self.ambient_K
            if cfg.gas_temperature in ("ambient", "infer")
            else float(cfg.gas_temperature)
        )


class SurfaceSamples(NamedTuple):
    """One surface's samples: positions ``xy`` (N, 2) [px], unit normals
    ``n`` (N, 2), lengths ``dl`` (N,) [m] and positions along it ``t`` (N,)
    in [0, 1]."""

    xy: np.ndarray
    n: np.ndarray
    dl: np.ndarray
    t: np.ndarray


@dataclasses.dataclass(frozen=True)
class Transport:
    """The plume's axis for the transport flux level: ``axis`` (``up``,
    ``down``, ``left``, ``right``: from the source towards the surfaces), the
    source's line along it in the flow's part of the region (``index``), that
    part (``crop``: row slice, column slice) and the source's line in the
    whole region (``region_index``)."""

    axis: str
    index: float
    crop: Tuple[slice, slice]
    region_index: float


@dataclasses.dataclass(frozen=True)
class FluxLevelPlan:
    """Whether a block's velocimetry takes its flux level from the transport
    of the line-integrated column: ``off_reason`` None when it does."""

    off_reason: Optional[str] = None

    @property
    def on(self) -> bool:
        return self.off_reason is None

    def off_note(self) -> str:
        """The record's note for a level not measured."""
        return f"off: {self.off_reason or ''}"


class Flow(NamedTuple):
    """A block's velocity [px per nominal frame interval] over the flow's
    part of the region: ``u``, ``v`` (frames, h, w) and that part's origin
    ``(x0, y0)`` in the region; ``reverse_speed``: when the flux level found
    no transport along the axis from the source (or the flow did not follow
    it), the transport's speed per line of the region [px per nominal frame
    interval] measured the other way (gas moving towards the source: a wrong
    source or axis), else None."""

    u: np.ndarray
    v: np.ndarray
    origin: Tuple[int, int]
    reverse_speed: Optional[np.ndarray] = None


@dataclasses.dataclass
class SurfaceFlux:
    """One surface's and species' flux over some frames: ``rate`` [kg/s] per
    frame (NaN without a valid column), ``pixels`` used per frame, and the
    sum over frames and pixels of (v_n sigma_c dl)^2 [(kg/s)^2] (the
    columns' random term)."""

    rate: np.ndarray
    pixels: np.ndarray
    column_variance: float
    #: For the detection limit (qogi.pipeline.detection), summable over blocks: the
    #: column-weighted |v_n| sums, each frame's median |v_n| and effective
    #: plume width [m] (NaN without gas).
    cv_sum: float = 0.0
    c_sum: float = 0.0
    vabs_median: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    width_m: np.ndarray = dataclasses.field(default_factory=lambda: np.zeros(0))
    #: The budget checks' sums (:class:`qogi.pipeline.flux_summary.FluxSummary`).
    summary: object = None


@dataclasses.dataclass
class BlockColumns:
    """The columns stage's output for one block: the column (proxy) field
    over the region per frame (B, h, w) float32, the surfaces' columns
    {species: (B, N)} [kg/m2] (NaN where invalid) and their 1-sigma, the
    pixel status counts, the frames with columns (``done``), the block's
    notes for ``Result.info`` and whether it was cancelled."""

    fields: np.ndarray
    columns: List[Dict[str, np.ndarray]]
    sigmas: List[Dict[str, np.ndarray]]
    counts: Dict[str, int]
    done: int
    info: Dict[str, object]
    cancelled: bool = False


@dataclasses.dataclass
class BlockOut:
    """The kept frames of one block: per surface {species:
    :class:`SurfaceFlux`}, the pixel status counts, kept maps and the
    velocimetry's notes (per-frame sums only: a run's memory does not grow
    with the pixels of its surfaces times its frames)."""

    flux: list
    n: int
    counts: Dict[str, int]
    maps: Dict[int, dict]
    velocity_info: Dict[str, object]
    cancelled: bool = False


@dataclasses.dataclass
class RunState:
    """What every stage and block of a run shares (see the module's docstring)."""

    rec: Recording
    cfg: QuantifyConfig
    scene: Scene
    surfaces: List[Surface]
    samples: List[SurfaceSamples]
    frames: range
    timebase: Any  # qogi.pipeline.timebase.FrameTimebase
    warnings: Any  # qogi.diagnostics.Diagnostics
    say: Callable[[float, str], None]  # raises Cancelled when the caller's progress says stop
    keep_maps: bool
    roi: Region
    horizontal: bool
    radiance_check: Any  # qogi.pipeline.checks.RadianceCheck
    channel_sign: np.ndarray
    background_temperature_K: float  # the typical background's temperature [K]
    t_start: float
    #: The run's notes for ``Result.info`` (velocimetry, background, source).
    info: Dict[str, object] = dataclasses.field(default_factory=dict)
    #: Up to 50 frames spread over the run (C, H, W each), until the stages
    #: that need them have run (background choice, source detection).
    sample_frames: Optional[np.ndarray] = None
    # Set by the stages, in order:
    background: Any = None  # background stage: pipeline.background.Background
    columns: Any = None  # columns stage: TruthColumns or InvertedColumns
    source: Optional[Tuple[float, float]] = None  # velocity stage (given or detected)
    transport: Optional[Transport] = None  # velocity stage
    crop: Tuple[slice, slice] = (slice(None), slice(None))
    blocks: List[BlockOut] = dataclasses.field(default_factory=list)

    @property
    def start(self) -> int:
        """The run's first frame in the recording."""
        return self.frames.start

    @property
    def map_every(self) -> int:
        """Frames between kept maps (every tenth of the run)."""
        return max(1, len(self.frames) // 10)
