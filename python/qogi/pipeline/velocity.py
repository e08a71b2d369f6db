"""Stage 3, the velocity: velocimetry on the column field (default: the
continuity-equation "fluid" flow, its flux level from the transport of the
line-integrated column when the source is known or detected), or a given
wind / exit speed; then the velocity along each surface sample's normal.

:func:`prepare` sets the run's source (given or detected) and the flow's
part of the region (:class:`~.state.Transport`); :func:`block_velocity`
makes a block's :class:`~.state.Flow` from its :class:`~.state.BlockColumns`;
:func:`normal_velocity` samples it on a surface.
"""

from __future__ import annotations

import math
from typing import Dict, Optional, Tuple

import numpy as np

from .. import workers as _workers_mod
from ..errors import Cancelled
from ..measure import velocimetry as vel
from . import selfchecks
from .config import QuantifyConfig
from .sampling import _bilinear
from .setup import wants_source
from .state import BlockColumns, Flow, FluxLevelPlan, RunState, Transport
from .surfaces import Region, _plume_image, detect_source

__all__ = ["prepare", "flux_level_plan", "block_velocity", "normal_velocity"]


def auto_pair_stride(displacement_px: float) -> int:
    """The frames between a flow pair's two frames where none is given:
    ~3 px of displacement per pair, at most every 4th frame (1 where the
    displacement per frame [px] is unknown)."""
    if not (np.isfinite(displacement_px) and displacement_px > 0):
        return 1
    return int(np.clip(round(3.0 / displacement_px), 1, 4))


def prepare(run: RunState) -> None:
    """The run's source (given, or detected on the sampled frames for the
    flux level of the default velocimetry; the sampled frames are released
    here) and, with a source and velocimetry, the flow's part of the region."""
    cfg = run.cfg
    source = cfg.source
    sample_frames, run.sample_frames = run.sample_frames, None
    # setup.prepare samples frames whenever wants_source(cfg).
    if wants_source(cfg) and sample_frames is not None and len(sample_frames) >= 2:
        try:
            source = detect_source(_plume_image(sample_frames))
            run.info["source_xy"] = [float(source[0]), float(source[1])]
            run.info["source"] = (
                f"detected at x={source[0]:.1f}, y={source[1]:.1f} "
                f"(for the flux level; give source= to set it)"
            )
        except ValueError as e:
            run.info["source"] = f"not detected: {e}"
    del sample_frames
    run.radiance_check.bad_pixels = run.radiance_check.total_pixels = 0  # counted again per block
    run.radiance_check.first_frame = None
    run.source = source
    if not cfg.methods.given_speed and cfg.velocity != "fluid":
        run.warnings.add(
            "velocity-texture",
            f"velocity={cfg.velocity} tracks the plume's texture, not the mass-weighted "
            "gas velocity a flux needs, and sets no flux level: on the synthetic lab "
            "releases such methods read 80-100 % low 2 cm above the exit and 16-54 % low "
            "at 12 cm (docs/velocimetry.md); for a rate use the default fluid method with "
            "the source (--source X,Y or source=)",
            method=cfg.velocity,
        )
    # The flow's part of the region (all of it without a source).
    if source is not None and not cfg.methods.given_speed:
        run.transport = _transport_crop(
            run.surfaces, source, run.roi, (run.rec.height, run.rec.width)
        )
        run.crop = run.transport.crop


def flux_level_plan(
    cfg: QuantifyConfig, source: Optional[Tuple[float, float]], frames: int
) -> FluxLevelPlan:
    """Whether a block of ``frames`` frames takes its flux level from the
    transport of the line-integrated column (time of flight of the plume's
    structures: mass conservation alone cannot fix it in a steady plume;
    docs/velocimetry.md): with the fluid method and a known source."""
    return FluxLevelPlan(
        "a method other than fluid"
        if cfg.velocity != "fluid"
        else "flux_level=False"
        if not cfg.flux_level
        else "no source given or detected"
        if source is None
        else "fewer than 3 frames"
        if frames < 3
        else None
    )


def normal_velocity(
    st: RunState, flows: Optional[Flow], xy: np.ndarray, n: np.ndarray, nb: int
) -> np.ndarray:
    """The velocity along each sample's normal [m/s], (frames, samples):
    the given speed, or the flow's (px per nominal frame interval) sampled
    at the surface (zero outside the flow's part; NaN without a flow)."""
    cfg, roi = st.cfg, st.roi
    # QuantifyConfig's check makes the given speed a number for its method.
    if cfg.velocity == "wind":
        assert cfg.wind_speed_m_s is not None
        return np.full((nb, len(xy)), float(cfg.wind_speed_m_s))
    if cfg.velocity == "exit":
        assert cfg.exit_velocity_m_s is not None
        return np.full((nb, len(xy)), float(cfg.exit_velocity_m_s))
    if flows is None:
        return np.full((nb, len(xy)), np.nan)
    fu, fv, (cx, cy) = flows.u, flows.v, flows.origin
    p = xy - [roi.x0 + cx, roi.y0 + cy]
    h, w = fu.shape[1:]
    inside = (p[:, 0] >= 0) & (p[:, 0] <= w - 1) & (p[:, 1] >= 0) & (p[:, 1] <= h - 1)
    u = _bilinear(fu, p)
    v = _bilinear(fv, p)
    return np.where(inside, (u * n[:, 0] + v * n[:, 1]) * st.scene.m_s_per_px_frame, 0.0)


def _transport_window(frame_rate_hz: float, n_frames: int) -> int:
    """Frame pairs per time-of-flight fit of the flux level
    (:func:`qogi.measure.velocimetry.transport_flux`'s ``window``): about
    :data:`qogi.measure.velocimetry.TRANSPORT_WINDOW_S` at the frame rate, where the
    block holds at least three such windows; else 0 (one fit over the block:
    on the M150 lab release's 2 s records two 1 s windows read its exact
    columns 0.98 -> 1.02 of the truth on average over seeds 0-3 but spread
    more, 0.05 -> 0.07, and seed 0 1.06 -> 1.13; docs/velocimetry.md)."""
    window = max(4, int(round(vel.TRANSPORT_WINDOW_S * frame_rate_hz)))
    return window if n_frames - 1 >= 3 * window else 0


def _pair_durations(intervals: np.ndarray, stride: int, n_frames: int) -> np.ndarray:
    """Duration [nominal frame intervals] of the pairs of frames 0, stride,
    2 stride, ... of a block whose consecutive frames are ``intervals`` apart."""
    t = np.concatenate([[0.0], np.cumsum(intervals)])[:n_frames]
    return np.diff(t[::stride])


def block_velocity(st: RunState, cols: BlockColumns, blk, say) -> Optional[Flow]:
    """The velocity at every frame of a block [px per nominal frame
    interval] over the flow's part of the region, or None (given speeds;
    fewer than 2 frames); its notes (pair stride, flux level) into the
    block's ``info``."""
    a, b = blk.read
    return _block_velocity(st, cols.fields, st.timebase.pair_intervals[a : b - 1], cols.info, say)


def _block_velocity(
    st: RunState,
    col_fields: np.ndarray,
    intervals: np.ndarray,
    velocity_info: Dict[str, object],
    say,
) -> Optional[Flow]:

    cfg, roi, crop, source = st.cfg, st.roi, st.crop, st.source
    done = col_fields.shape[0]
    if cfg.methods.given_speed or done < 2:
        return None
    # Every frame's field (also for the time-averaged order: the gas
    # moves, the averaged field does not).
    velocity_frames = col_fields
    source_mask = None
    if source is not None and cfg.velocity == "fluid":  # the exit: only the fluid flow takes it
        sx, sy = source[0] - roi.x0, source[1] - roi.y0
        yy, xx = np.mgrid[0 : velocity_frames.shape[1], 0 : velocity_frames.shape[2]]
        rad = 6.0
        source_mask = ((xx - sx) ** 2 + (yy - sy) ** 2) <= rad**2
        if not source_mask.any():
            source_mask = None
    # With the fluid method and a known source, the flux level comes from
    # the transport of the line-integrated column (time of flight of the
    # plume's structures: mass conservation alone cannot fix it in a
    # steady plume; docs/velocimetry.md).
    plan = flux_level_plan(cfg, source, done)
    if plan.on:
        # plan.on needs a source with the fluid method: prepare set the transport.
        assert st.transport is not None
        axis, index, region_index = st.transport.axis, st.transport.index, st.transport.region_index
    field = velocity_frames[:, crop[0], crop[1]]
    mask = source_mask[crop[0], crop[1]] if source_mask is not None else None
    # The flows' scale: the 99.5th percentile of (up to) 100 frames spread
    # over the block.
    scale = np.percentile(field[:: max(1, field.shape[0] // 100)], 99.5)
    norm = np.ascontiguousarray(field / scale if scale > 0 else field, dtype=np.float32)
    # The flux level's transport along the whole region (the plume's
    # structures beyond the flow's part constrain it too;
    # docs/velocimetry.md), on a worker thread while the flow runs.
    job = None
    if plan.on:
        # Only the plume's part of each line (vel.transport_band): noise
        # common to a line would draw the flux level low in faint plumes.
        band = vel.transport_band(velocity_frames.mean(axis=0), axis)
        # How much the plume's column fluctuates (qogi.pipeline.selfchecks): a
        # steady column's pattern need not travel at the gas's speed.
        velocity_info["column_fluctuation"] = selfchecks.column_fluctuation(
            _band_line_sums(velocity_frames, band, axis)
        )
        window = _transport_window(st.scene.frame_rate, done)
        velocity_info["transport_window"] = window
        job = _workers_mod.current().submit(
            lambda: vel.transport_flux(
                velocity_frames, axis, region_index, intervals=intervals, window=window, mask=band
            ),
            "qogi-transport",
        )
    # Pairs `stride` frames apart where the plume moves little per frame
    # (at 100 Hz a lab plume crosses ~1 px per frame): ~3 px per pair, at
    # most every 4th frame, with the transport's flux level (which sets
    # the level; the flow gives the pattern: the same rates to 0.1 % on
    # the lab releases at strides 1-4, docs/velocimetry.md).
    stride = cfg.pair_stride
    if stride is None:
        stride = auto_pair_stride(vel.typical_displacement(field, axis)) if plan.on else 1
    stride = max(1, min(int(stride), (norm.shape[0] - 1) // 2))
    reduced = cfg.pair_stride is not None and stride != cfg.pair_stride
    if reduced and not st.warnings.has("pair-stride-reduced"):
        st.warnings.add(
            "pair-stride-reduced",
            f"pair_stride={cfg.pair_stride} was reduced to {stride}: a block of "
            f"{norm.shape[0]} frames holds at least two pairs only with a stride up to "
            f"{stride} (give more frames, or a smaller stride)",
            given=int(cfg.pair_stride or 0),
            used=int(stride),
        )
    velocity_info["pair_stride"] = stride
    try:
        # The pairs' displacements go into the first frames of two (frames,
        # h, w) stacks that then become the frame velocities in place: the
        # block holds two velocity stacks, not the sequence's u, v, quality
        # and validity beside the frame velocities' u and v.
        paired = norm[::stride]
        fvel = (np.empty(paired.shape, np.float32), np.empty(paired.shape, np.float32))
        seq = vel.optical_flow_sequence(
            paired,
            method=cfg.velocity,
            source_mask=mask,
            warm_start=True,
            workers=0,
            progress=lambda fr_: say(0.6 + 0.3 * fr_, "velocimetry"),
            out=(fvel[0][:-1], fvel[1][:-1]),
            keep_quality=False,
        )
        # Each pair's displacement over its real duration (time_s), in px per
        # `stride` nominal frame intervals.
        per = (stride / _pair_durations(intervals, stride, done)).astype(np.float32)
        if not np.all(per == 1.0):
            seq.u *= per[:, None, None]
            seq.v *= per[:, None, None]
        fvel = vel.frame_velocity_in_place(*fvel)
        if stride > 1:
            fvel = vel.interpolate_frame_velocity(*fvel, stride, norm.shape[0])
    except KeyboardInterrupt:
        # Ctrl-C inside the velocimetry (or its own loops' stop): the block
        # is dropped and the run returns the blocks finished before it.
        raise Cancelled("quantification cancelled", partial=None) from None
    finally:
        if job is not None:
            job.wait()
    uv = None
    flux_note = plan.off_note()
    level_found = False
    if plan.on:
        try:
            assert job is not None  # submitted above when plan.on
            tf = job.result()  # its error is reported as the level's note
            velocity_info["transport_unexplained"] = transport_unexplained(tf)
            velocity_info["transport_frames_in_view"] = frames_in_view(tf, region_index)
            velocity_info["transport_speed_m_s"] = transport_speed(tf) * st.scene.m_s_per_px_frame
            # In the flow field's units and lines.
            lines = crop[0] if axis in ("up", "down") else crop[1]
            tf = tf.lines(lines, scale=1.0 / scale if scale > 0 else 1.0)
            u, v, level = vel.calibrate_flux_level(
                None, norm, axis, index, transport=tf, frame_velocities=fvel
            )
            uv = (u, v)
            level_found = bool(np.isfinite(level).any())
            flux_note = (
                f"on: transport of the line-integrated column, axis {axis}"
                if level_found
                else f"on: transport velocity of each line along axis {axis} (the "
                f"flow did not follow the transport, e.g. wind faster than it "
                f"can track)"
            )
        except ValueError as e:
            flux_note = f"off: {e}"
    if uv is None:
        uv = fvel
    velocity_info["flux_level"] = flux_note
    # No transport along the axis from the source, or a flow that does not
    # follow it: the gas may move the other way (a source given at the
    # wrong end). The transport the other way is what is known of its speed
    # then (the budget's direction check: pipeline/flux._speed_floor).
    reverse = None
    if plan.on and not level_found:
        reverse = _reverse_transport_speed(velocity_frames, axis, intervals)
    # The analysed part and its origin in the region (no velocity outside it).
    return Flow(uv[0], uv[1], (crop[1].start, crop[0].start), reverse)


def transport_unexplained(tf: vel.TransportFlux) -> float:
    """The share of the plume's column the flux level's time of flight does
    not explain (:attr:`qogi.measure.velocimetry.TransportFlux.unexplained`
    averaged over the solved lines, weighted by their time-averaged column);
    NaN when no line was solved. Its self-check is
    :mod:`qogi.pipeline.selfchecks`' ``transport_unexplained``."""
    u = tf.unexplained
    if u is None:
        return float("nan")
    w = np.asarray(tf.line_column, float)
    ok = np.isfinite(u) & np.isfinite(w) & (w > 0)
    return float(np.sum(u[ok] * w[ok]) / np.sum(w[ok])) if ok.any() else float("nan")


def transport_speed(tf: vel.TransportFlux) -> float:
    """The speed the flux level's time of flight measured: the median of
    its solved lines' displacements [px per nominal frame interval]; NaN
    when no line was solved (or the median is not positive)."""
    d = np.asarray(tf.displacement, float)
    d = d[np.isfinite(d)]
    m = float(np.median(d)) if d.size else float("nan")
    return m if m > 0 else float("nan")


def frames_in_view(tf: vel.TransportFlux, source_index: float) -> float:
    """How many frames the gas stays in view: the lines from the source's
    line ``source_index`` to the frame's far edge along the transport's axis
    over the transport's displacement per frame (:func:`transport_speed`)
    [frames]; NaN when no line was solved. Its self-check is
    :mod:`qogi.pipeline.selfchecks`' ``transport_frames_in_view``."""
    speed = transport_speed(tf)
    if not math.isfinite(speed):
        return float("nan")
    n = len(tf.displacement)
    path = float(source_index) if tf.axis in ("up", "left") else n - 1 - float(source_index)
    return max(path, 0.0) / speed


#: Frames per step of :func:`_band_line_sums` (its scratch: this many frames).
BAND_CHUNK_FRAMES = 32


def _band_line_sums(frames: np.ndarray, band: np.ndarray, axis: str) -> np.ndarray:
    """The sums of ``frames * band`` (T, H, W) across each line along
    ``axis`` (T, lines), float32, made :data:`BAND_CHUNK_FRAMES` frames at a
    time (the same sums, without a second stack of the block's frames)."""
    across = 2 if axis in ("up", "down") else 1
    return np.concatenate(
        [
            (frames[k : k + BAND_CHUNK_FRAMES] * band).sum(axis=across)
            for k in range(0, frames.shape[0], BAND_CHUNK_FRAMES)
        ]
    )


_OPPOSITE = {"up": "down", "down": "up", "left": "right", "right": "left"}


def _reverse_transport_speed(
    frames: np.ndarray, axis: str, intervals: np.ndarray
) -> Optional[np.ndarray]:
    """|mass-weighted velocity| per line of the region [px per nominal frame
    interval] of the transport along the axis opposite to ``axis`` (no
    source line), or None when that finds no transport either."""

    try:
        tf = vel.transport_flux(frames, _OPPOSITE[axis], None, intervals=intervals)
    except ValueError:
        return None
    speed = np.abs(np.asarray(tf.velocity, float))
    return speed if np.isfinite(speed).any() else None


def _transport_crop(surfaces, source, roi: Region, shape: Tuple[int, int]) -> Transport:
    """The plume's axis in the image (``up``, ``down``, ``left``, ``right``:
    from the source towards the surfaces), the source's line along it in the
    part of the region the flow uses (index), that part: up to a margin
    beyond the farthest surface (the gas leaving through the cut is the flow
    balance's outflow), and the source's line in the whole region (for the
    transport flux level, measured along all of it)."""
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
    return Transport(axis, index, crop, region_index)
