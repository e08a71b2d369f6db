"""The run: :func:`quantify` checks its inputs and chains the stages.

recording (:mod:`.setup`) -> alignment (:mod:`.align`: jitter and filter-wheel
timing) -> background (:mod:`.background`) -> columns
(:mod:`.columns`) -> velocity (:mod:`.velocity`) -> flux (:mod:`.flux`) ->
rate and budget (:mod:`.budget`), the middle three block by block
(:mod:`qogi.pipeline.timebase`: blocks of bounded length with a few frames of overlap,
cut where ``time_s`` has a gap). Every stage takes the
:class:`~.state.RunState` and returns (or sets on it) what the next one needs.
"""

from __future__ import annotations

import ctypes
import math
import sys
import time
from typing import Callable, List, Optional, Sequence, Union

from .. import workers as _workers_mod
from ..audit import run_record
from ..errors import Cancelled
from ..io.hdf5 import open_recording
from ..io.recording import Recording
from . import align, background, budget, columns, flux, setup, velocity
from .checks import check_surfaces
from .config import QuantifyConfig
from .result import Result
from .setup import check_inputs
from .state import BlockOut, RunState
from .surfaces import Surface
from .timebase import stream_blocks

__all__ = ["quantify", "BLOCK_BYTES", "MIN_BLOCK_FRAMES", "MIN_BLOCK_SECONDS"]

#: Frames per block (the pipeline's memory bound) when not configured: the
#: block's float32 fields (column field, flow, frame velocities, their
#: normalised copy, ~8 per frame) within this many bytes.
BLOCK_BYTES = 1 << 28
#: A block holds at least this much record [s] (the transport's flux level is
#: a time average over the block; every validation release at 15 Hz, 10 s,
#: is one block), ...
MIN_BLOCK_SECONDS = 10.0
#: ... or this many frames when fewer (100 Hz: 4.5 s; a 2 s release is one
#: block).
MIN_BLOCK_FRAMES = 450


def quantify(
    recording: Union[Recording, str],
    surfaces: Sequence[Surface],
    config: Optional[QuantifyConfig] = None,
    progress: Optional[Callable[[float, str], Optional[bool]]] = None,
    keep_maps: bool = False,
) -> Result:
    """Emission-rate time series of each species through each control surface.

    Parameters
    ----------
    recording : qogi.Recording or path
    surfaces : list of qogi.Surface
        Lines or polylines in pixel coordinates; sign convention in
        :mod:`qogi.pipeline.surfaces` (left-hand normal positive), or oriented away from
        ``config.source`` when given.
    config : QuantifyConfig or dict, optional
        A dict is read as :meth:`QuantifyConfig.from_dict` reads it (the flat
        keys; an unknown key is a :class:`qogi.UsageError`).
    progress : callable(fraction, message) -> bool or None
        qogi's progress protocol (:mod:`qogi.progress`): returning False
        cancels: :class:`qogi.Cancelled` is raised with the partial result of
        the frames finished so far (``.partial``).
    keep_maps : bool
        Keep per-frame column-density and velocity maps (``Result.maps``).

    Returns
    -------
    qogi.Result
    """

    cfg = _config(config)
    rec = open_recording(recording) if not isinstance(recording, Recording) else recording
    surfaces = [s if isinstance(s, Surface) else Surface(s) for s in surfaces]
    surfaces = [Surface(s.points, s.name or f"S{k + 1}") for k, s in enumerate(surfaces)]
    if cfg.source is not None:
        surfaces = [s.oriented_away_from(cfg.source) for s in surfaces]
    check_inputs(rec, surfaces, cfg)

    check_surfaces(surfaces)
    # The scene facts not given are the recording's (qogi.pipeline.settings.complete):
    # the stages see them all; the result keeps the config as given and says
    # which values came from the recording.
    run_cfg, taken = cfg.completed(rec.scene)
    started = time.time()
    with _workers_mod.owned_workers():
        try:
            result = _run(rec, surfaces, run_cfg, progress, keep_maps)
        except Cancelled as e:
            if isinstance(e.partial, Result):
                e.partial.audit = run_record(rec, started, time.time())
            raise
    result.audit = run_record(rec, started, time.time())
    result.config = cfg
    result.info["from_recording"] = {k: _plain(v) for k, v in taken.items()}
    # What opening a camera file noticed (scene facts at factory defaults,
    # assumed pressure, dropped frames) and where each scene fact came from.
    # (Dropped frames are the pipeline's own finding too: reported once.)
    result.warnings.extend_unique(
        w
        for w in (getattr(rec, "warnings", None) or ())
        if not (w.code == "frames-dropped" and result.warnings.has("frames-dropped"))
    )
    scene_origin = getattr(rec, "scene_origin", None)  # set by qogi.io.open
    if scene_origin:
        result.info["scene_origin"] = dict(scene_origin)
    return result


def _c_malloc_trim() -> Optional[Callable[[int], int]]:
    """glibc's ``malloc_trim`` (None on other C libraries and platforms)."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        trim = ctypes.CDLL(None).malloc_trim  # the process's own C library
    except (OSError, AttributeError):  # musl and others have none
        return None
    trim.argtypes = [ctypes.c_size_t]
    trim.restype = ctypes.c_int
    return trim


_MALLOC_TRIM = _c_malloc_trim()


def _fix_mmap_threshold() -> None:
    """Serve every allocation of 1 MiB or more by its own mapping, returned to
    the system when freed (glibc's ``mallopt(M_MMAP_THRESHOLD, 1 MiB)``;
    nothing on other C libraries). By default glibc raises that threshold to
    the largest block freed so far (up to 32 MB), after which a stage's
    temporaries (a block's normalised field, the flow's buffers) come from
    the heap and stay resident until the next trim: 22 MB of the 15 Hz
    320 x 240 benchmark's peak (319 -> 297 MB with 150-frame blocks).
    Process-wide, set when the pipeline is imported (before the run's first
    large arrays); values are untouched."""
    if not sys.platform.startswith("linux"):
        return
    try:
        mallopt = ctypes.CDLL(None).mallopt
    except (OSError, AttributeError):
        return
    mallopt.argtypes = [ctypes.c_int, ctypes.c_int]
    mallopt.restype = ctypes.c_int
    mallopt(-3, 1 << 20)  # M_MMAP_THRESHOLD


_fix_mmap_threshold()


def _release_free_memory() -> None:
    """Hands the C heap's free pages back to the system (glibc's
    ``malloc_trim(0)``, every arena; nothing elsewhere), between the run's
    stages and blocks. glibc raises its threshold for serving an allocation
    by its own mapping to the largest block freed so far (up to 32 MB), so
    after a stage frees a stack of frames, the next stages' frames and
    sub-blocks come from the heap, whose freed pages it keeps: on the 15 Hz
    320x240 benchmark (benchmarks/bench_memory.py) the process held ~140 MB
    more at each block's start, and more the longer the run. Values are
    untouched."""
    if _MALLOC_TRIM is not None:
        _MALLOC_TRIM(0)


def _plain(v):
    """A JSON-friendly copy of a setting's value (lists for tuples)."""
    return list(v) if isinstance(v, (tuple, list)) else v


def _config(config) -> QuantifyConfig:
    """The run's config from :func:`quantify`'s ``config`` argument."""
    if config is None:
        return QuantifyConfig()
    if isinstance(config, QuantifyConfig):
        return config
    if isinstance(config, dict):
        return QuantifyConfig.from_dict(config)
    raise TypeError(
        f"config must be a qogi.QuantifyConfig, a dict of its keys (e.g. "
        f"{{'species': ['CH4']}}) or None; got {type(config).__name__} {config!r:.60}"
    )


def _run(
    rec: Recording, surfaces: List[Surface], cfg: QuantifyConfig, progress, keep_maps: bool
) -> Result:
    """The stages in order; a cancel raises :class:`qogi.Cancelled` with the
    Result of the blocks finished (``complete=False``)."""

    run = setup.prepare(rec, surfaces, cfg, progress, keep_maps)
    for stage in (align, background, columns, velocity):
        stage.prepare(run)
        _release_free_memory()
    # Stream the run in blocks (bounded memory), cut at gaps in time_s.
    blocks = stream_blocks(run.timebase.segments, _block_frames(cfg, rec), overlap=4)
    for i, blk in enumerate(blocks):
        label = f" (block {i + 1}/{len(blocks)})" if len(blocks) > 1 else ""

        def say_block(fraction: float, message: str, i=i, label=label) -> None:
            run.say((i + fraction) / len(blocks), message + label)

        try:
            out = _block(run, blk, say_block)
        except Cancelled:
            out = None
        _release_free_memory()
        if out is not None:
            run.blocks.append(out)
        if out is None or out.cancelled:
            run.radiance_check.report(run.warnings)
            raise Cancelled(
                "quantification cancelled", partial=budget.finish(run, complete=False)
            ) from None
    run.radiance_check.report(run.warnings)
    return budget.finish(run, complete=True)


def _block(run: RunState, blk, say) -> BlockOut:
    """One block through columns -> velocity -> flux."""
    cols = columns.block_columns(run, blk, say)
    _release_free_memory()
    if cols.cancelled:
        return flux.block_flux(run, blk, cols, None, None)
    flows = velocity.block_velocity(run, cols, blk, say)
    vn = [
        velocity.normal_velocity(run, flows, s.xy, s.n, cols.fields.shape[0]) for s in run.samples
    ]
    out = flux.block_flux(run, blk, cols, vn, flows)
    if run.keep_maps and flows is not None:
        out.maps = flux.block_maps(run, blk, cols, flows)
    return out


def _block_frames(cfg: QuantifyConfig, rec: Recording) -> int:
    """Frames per block: ``cfg.block_frames``, else as many as fit
    :data:`BLOCK_BYTES` and at least :data:`MIN_BLOCK_SECONDS` of record
    (at most :data:`MIN_BLOCK_FRAMES` for that floor). At 15 Hz 320 x 240:
    150 frames, a peak of ~300 MB however long the record (it was 450
    frames and 592 MB; benchmarks/bench_memory.py)."""
    if cfg.block_frames is not None:
        return cfg.block_frames
    per_frame = 8 * 4 * rec.height * rec.width
    fps = float(rec.camera.frame_rate_hz or 0.0)
    floor = (
        min(MIN_BLOCK_FRAMES, math.ceil(MIN_BLOCK_SECONDS * fps)) if fps > 0 else MIN_BLOCK_FRAMES
    )
    return int(max(floor, BLOCK_BYTES // per_frame))
