"""Stage 0, the recording: the run's checks, scene constants, timebase and
surface samples (:func:`prepare` makes the :class:`~.state.RunState`), and
up to 50 frames spread over the run for the stages that choose from the scene
(background, source)."""

from __future__ import annotations

import time
from typing import List, Optional, Sequence

import numpy as np

from ..diagnostics import Diagnostics
from ..errors import Cancelled
from ..io.recording import Recording
from ..progress import Progress, report
from . import checks
from .config import QuantifyConfig
from .state import RunState, Scene, SurfaceSamples
from .surfaces import Region, Surface
from .timebase import frame_timebase

__all__ = ["check_inputs", "prepare"]


def check_inputs(rec: Recording, surfaces: Sequence[Surface], cfg: QuantifyConfig) -> None:
    """The call's own mistakes, before any work (``cfg`` completed by the
    recording's scene facts first: :meth:`QuantifyConfig.completed`)."""
    cfg, _ = cfg.completed(rec.scene)
    if not surfaces:
        raise ValueError("no control surface given; draw one or use qogi.auto_surfaces")
    w, h = rec.width, rec.height
    for k, s in enumerate(surfaces):
        p = np.asarray(s.points)
        if (
            np.any(p[:, 0] < 0)
            or np.any(p[:, 0] > w - 1)
            or np.any(p[:, 1] < 0)
            or np.any(p[:, 1] > h - 1)
        ):
            raise ValueError(
                f"surface {s.name or k} has points outside the {w}x{h} image: {s.points}"
            )
    if cfg.conditions.infers_temperature and rec.n_channels < 2:
        raise ValueError(
            "gas_temperature='infer' needs a camera with >= 2 channels; this recording "
            f"has {rec.n_channels}: give the gas temperature or use 'ambient'"
        )
    if cfg.methods.truth_columns and (
        rec.truth is None
        or not all(f"column_density_kg_m2_{sp}" in rec.truth.datasets for sp in cfg.species)
    ):
        raise ValueError(
            "column_density='truth' needs a synthetic recording with truth maps "
            "(qogi synth ... --truth-maps)"
        )
    if cfg.frames is not None and cfg.frames[1] > rec.n_frames:
        raise ValueError(f"frames {cfg.frames} exceed the recording's {rec.n_frames} frames")
    if isinstance(cfg.background, Region):
        r = cfg.background.clip(w, h)
        if r.x1 <= r.x0 or r.y1 <= r.y0:
            raise ValueError(f"background region {cfg.background} lies outside the {w}x{h} image")


def _reporter(progress: Optional[Progress]):
    """``say(fraction, message)``: reports to ``progress`` (qogi's progress
    protocol, :func:`qogi.progress.report`: fraction clamped to [0, 1]) and
    raises :class:`qogi.Cancelled` when it returns False."""

    def say(fraction: float, message: str) -> None:
        try:
            report(progress, fraction, message)
        except Cancelled:
            raise Cancelled("quantification cancelled") from None

    return say


def prepare(
    rec: Recording, surfaces: List[Surface], cfg: QuantifyConfig, progress, keep_maps: bool
) -> RunState:
    """The run's state before any stage: its frames and timebase (with the
    checks of the frame count, the timebase and the source), the surfaces'
    samples, the background's sign and typical temperature, and the frames
    the background's choice and the source detection sample."""

    t_start = time.perf_counter()
    scene = Scene(rec, cfg)
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
    horizontal = all(
        abs(np.diff(np.asarray(s.points)[:, 0])).sum()
        >= abs(np.diff(np.asarray(s.points)[:, 1])).sum()
        for s in surfaces
    )
    samples = []
    for s in surfaces:
        xy, n, dl = s.samples(step_px=1.0)
        t = np.concatenate([[0.0], np.cumsum(dl)])[:-1] + 0.5 * dl
        samples.append(SurfaceSamples(xy, n, dl * scene.pixel_m, t / s.length_px))

    radiance_check = checks.RadianceCheck(rec.channels)
    t_bg_guess = rec.scene.background_temperature_K
    if t_bg_guess is None:
        first = rec.frame(start, quantity="radiometric_temperature")
        t_bg_guess = float(np.nanmedian(first))
    channel_sign = np.full(rec.n_channels, 1.0 if scene.gas_K >= t_bg_guess else -1.0)
    run = RunState(
        rec=rec,
        cfg=cfg,
        scene=scene,
        surfaces=surfaces,
        samples=samples,
        frames=frames,
        timebase=tb,
        warnings=warnings,
        say=_reporter(progress),
        keep_maps=keep_maps,
        roi=roi,
        horizontal=horizontal,
        radiance_check=radiance_check,
        channel_sign=channel_sign,
        background_temperature_K=t_bg_guess,
        t_start=t_start,
        crop=(slice(0, h), slice(0, w)),
    )
    if cfg.source is not None:
        run.info["source_xy"] = [float(cfg.source[0]), float(cfg.source[1])]
    # Up to 50 frames spread over the run: the background's choice and static
    # shape and, without a given source, the plume's source for the flux
    # level of the default velocimetry (the surfaces keep their own
    # orientation).
    if wants_source(cfg) or (
        not isinstance(cfg.background, Region) and cfg.background != "percentile"
    ):
        sample = list(frames)[:: max(1, len(frames) // 50)][:50]
        run.sample_frames = np.asarray(
            [rec.frame(f, quantity="radiance") for f in sample], dtype=np.float64
        )
        for f, fr in zip(sample, run.sample_frames):
            radiance_check(fr[None].astype(np.float32), f)
    return run


def wants_source(cfg: QuantifyConfig) -> bool:
    """True when the run detects the plume's source itself (for the flux
    level of the default velocimetry)."""
    return (
        cfg.source is None
        and cfg.velocity == "fluid"
        and cfg.flux_level
        and not cfg.methods.truth_columns
    )
