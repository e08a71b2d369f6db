"""Velocimetry: the projected velocity of a gas plume from two frames.

Every method estimates, from frames ``prev`` (time t) and ``next`` (t + one
frame), the forward displacement ``(u, v)`` [px/frame] of the gas at each pixel
of ``prev`` (x right, y down). Frames are one channel: band radiance (better:
its contrast against the background) or column density [kg/m2]; any linear
unit works. Speeds in m/s follow from the camera geometry (thesis eq. 7-11)::

    speed [m/s] = displacement [px/frame] * distance_m * ifov_rad * frame_rate_hz

Which method when
-----------------
``"fluid"`` (default)
    Continuity equation on column density, ``d(rho)/dt + div(rho u) = 0``
    (Liu & Shen, J. Fluid Mech. 614, 2008), solved coarse to fine. It measures
    the column-density-weighted velocity, the one the flux needs, stays
    unbiased where the plume spreads or dilutes, and carries the mass flux
    through steady featureless stretches (the plume base) where every
    brightness-constancy method reads near zero. From rest it starts from a
    dense inverse patch search (OpenCV's DIS) between its coarse and finest
    levels, which resolves rotation and shear (~0.05 px on a real infrared
    frame); warm-started pairs refine the previous flow. Give it column
    density (or a contrast proportional to it, zero where there is no gas),
    and the stack exit as ``source_mask``. ~180 frames/s per core on
    320 x 256 (docs/velocimetry.md, Speed).
``"horn_schunck"``
    The same solver with brightness constancy (Horn & Schunck 1981, with a
    pyramid and warping). Smooth dense flow of textured radiance frames; biased
    in spreading plumes.
``"lucas_kanade"``
    Dense pyramidal Lucas-Kanade: local least squares in a Gaussian window.
    Fast local estimates on well-textured frames; marks untextured pixels
    invalid (aperture problem).
``"farneback"``, ``"dis"``
    OpenCV's polynomial-expansion and dense-inverse-search flows, as widely
    used baselines.
``"piv"``
    Window-deformation FFT cross-correlation (PIV), with a correlation
    quality per vector. Strongly textured plumes and large displacements;
    spatial resolution about one window (16 px).

All but ``"fluid"`` assume the pattern is only moved, and so track texture,
not mass. For large displacements (15 Hz cameras: ~20 px/frame near the exit)
use the pyramids (``levels``) and the warm start of :func:`optical_flow_sequence`.

For a flux through a surface use :func:`plume_frame_velocity`: the velocity
at the frame times (:func:`frame_velocity`) with the flux level taken from
the transport of the plume's line-integrated column (:func:`transport_flux`,
:func:`calibrate_flux_level`), which mass conservation per frame pair leaves
to the regulariser.

Post-processing (pure functions returning new arrays and masks):
:func:`normalised_median_test`, :func:`replace_vectors`, :func:`validate`,
:func:`temporal_filter`, :func:`plume_mask`, :func:`restrict_to_mask`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Optional, Sequence, Tuple, Union, overload

import numpy as np

from .. import _engine
from ..errors import Cancelled

__all__ = [
    "METHODS",
    "DEFAULT_METHOD",
    "FluidFlowOptions",
    "HornSchunckOptions",
    "LucasKanadeOptions",
    "FarnebackOptions",
    "DisOptions",
    "PivOptions",
    "MedianTestOptions",
    "TemporalFilterOptions",
    "PlumeMaskOptions",
    "Flow",
    "FlowSequence",
    "FlowEstimator",
    "options_for",
    "optical_flow",
    "optical_flow_sequence",
    "metres_per_second_per_pixel_per_frame",
    "to_metres_per_second",
    "normalised_median_test",
    "replace_vectors",
    "validate",
    "temporal_filter",
    "frame_velocity",
    "frame_velocity_in_place",
    "invert_displacement",
    "AXES",
    "TransportFlux",
    "transport_flux",
    "transport_band",
    "calibrate_flux_level",
    "plume_frame_velocity",
    "plume_mask",
    "restrict_to_mask",
    "set_num_threads",
    "get_num_threads",
]

FluidFlowOptions = _engine.FluidFlowOptions
HornSchunckOptions = _engine.HornSchunckOptions
LucasKanadeOptions = _engine.LucasKanadeOptions
FarnebackOptions = _engine.FarnebackOptions
DisOptions = _engine.DisOptions
PivOptions = _engine.PivOptions
MedianTestOptions = _engine.MedianTestOptions
TemporalFilterOptions = _engine.TemporalFilterOptions
PlumeMaskOptions = _engine.PlumeMaskOptions

#: Method name -> its options class (fields and defaults as in the C++ engine).
METHODS = {
    "fluid": FluidFlowOptions,
    "horn_schunck": HornSchunckOptions,
    "lucas_kanade": LucasKanadeOptions,
    "farneback": FarnebackOptions,
    "dis": DisOptions,
    "piv": PivOptions,
}
DEFAULT_METHOD = "fluid"

ArrayLike = Union[np.ndarray, Sequence]


def _frame(a: ArrayLike, name: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be a 2-D frame (H, W); got shape {arr.shape}")
    if not np.issubdtype(arr.dtype, np.number):
        raise ValueError(f"{name} must hold numbers; got dtype {arr.dtype}")
    return np.ascontiguousarray(arr, dtype=np.float32)


@overload
def _mask(a: None, name: str, shape) -> None: ...
@overload
def _mask(a: ArrayLike, name: str, shape) -> np.ndarray: ...
def _mask(a: Optional[ArrayLike], name: str, shape) -> Optional[np.ndarray]:
    if a is None:
        return None
    arr = np.asarray(a)
    if arr.shape != tuple(shape):
        raise ValueError(f"{name} must have the frames' shape {tuple(shape)}; got {arr.shape}")
    return np.ascontiguousarray(arr != 0, dtype=np.uint8)


def options_for(method: str = DEFAULT_METHOD, **fields):
    """The options object of ``method``, defaults overridden by ``fields``.

    >>> options_for("piv", window_size=32).window_size
    32
    """
    try:
        cls = METHODS[method]
    except KeyError:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}") from None
    return cls(**fields)


@dataclass
class Flow:
    """Displacement field of one frame pair.

    Attributes
    ----------
    u, v : ndarray (H, W) float32, px/frame
        Displacement to the right and downwards of the gas at each pixel of the
        first frame.
    quality : ndarray (H, W) float32 in [0, 1]
        Per-vector quality, 1 = best. Residual-based inlier weight for the
        variational and OpenCV methods, eigenvalue ratio for Lucas-Kanade,
        correlation coefficient for PIV.
    valid : ndarray (H, W) bool
        Vectors the method stands by: inside the gas mask, supported by data.
    residual_ratio : float
        Mean |data residual| after the motion over that at zero motion (0 = the
        motion explains every change between the frames).
    method : str
    """

    u: np.ndarray
    v: np.ndarray
    quality: np.ndarray
    valid: np.ndarray
    residual_ratio: float
    method: str

    @property
    def speed(self) -> np.ndarray:
        """|(u, v)| [px/frame]."""
        return np.hypot(self.u, self.v)

    def in_metres_per_second(
        self, distance_m: float, ifov_rad: float, frame_rate_hz: float
    ) -> tuple[np.ndarray, np.ndarray]:
        """(u, v) in m/s; see :func:`to_metres_per_second`."""
        k = metres_per_second_per_pixel_per_frame(distance_m, ifov_rad, frame_rate_hz)
        return self.u * k, self.v * k


class FlowEstimator:
    """One velocimetry method, reusable over many frame pairs (keeps buffers).

    Parameters
    ----------
    method : str, default "fluid"
        One of :data:`METHODS`.
    options : options object, optional
        ``METHODS[method]`` instance; defaults when omitted.
    source_mask : array (H, W) of bool, optional
        Fluid method only: where gas enters the image (the stack exit). Mass
        conservation is not enforced there.
    """

    def __init__(self, method: str = DEFAULT_METHOD, options=None, source_mask=None):
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
        if options is None:
            options = METHODS[method]()
        elif not isinstance(options, METHODS[method]):
            raise TypeError(
                f"options for method {method!r} must be "
                f"{METHODS[method].__name__}; got {type(options).__name__}"
            )
        self.method = method
        self.options = options
        self._impl = _engine.FlowEstimator(options)
        self._source_shape: Optional[Tuple[int, ...]] = None
        if source_mask is not None:
            self.set_source_mask(source_mask)

    def set_source_mask(self, source_mask) -> None:
        """Set (or clear, with None) where gas enters the image (fluid only)."""
        if source_mask is None:
            self._impl.set_source_mask(None)
            self._source_shape = None
            return
        arr = np.asarray(source_mask)
        if arr.ndim != 2:
            raise ValueError(f"source_mask must be 2-D; got shape {arr.shape}")
        self._impl.set_source_mask(np.ascontiguousarray(arr != 0, dtype=np.uint8))
        self._source_shape = arr.shape

    def calc(
        self,
        prev: ArrayLike,
        next: ArrayLike,
        mask: Optional[ArrayLike] = None,
        flow: Optional[Union[Flow, tuple]] = None,
    ) -> Flow:
        """Displacement from ``prev`` to ``next``.

        Parameters
        ----------
        prev, next : array (H, W)
            Frames (radiance, contrast or column density), finite, at least
            16 x 16 px.
        mask : array (H, W) of bool, optional
            Gas mask; vectors outside it are invalid.
        flow : Flow or (u, v), optional
            Warm start, e.g. the previous pair's result.

        Returns
        -------
        Flow
        """
        p, n, m = self._inputs(prev, next, mask)
        u0 = v0 = None
        if flow is not None:
            u0, v0 = (flow.u, flow.v) if isinstance(flow, Flow) else flow
            u0 = np.ascontiguousarray(u0, dtype=np.float32)
            v0 = np.ascontiguousarray(v0, dtype=np.float32)
            if u0.shape != p.shape or v0.shape != p.shape:
                raise ValueError(
                    f"the warm-start flow must have the frames' shape {p.shape}; "
                    f"got {u0.shape} and {v0.shape}"
                )
        u, v, q, valid, ratio = self._impl.calc(p, n, m, u0, v0)
        return Flow(u, v, q, valid.astype(bool), float(ratio), self.method)

    def _inputs(self, prev: ArrayLike, next: ArrayLike, mask: Optional[ArrayLike]):
        """The frames and mask as the engine takes them, checked."""
        p = _frame(prev, "prev")
        n = _frame(next, "next")
        if n.shape != p.shape:
            raise ValueError(f"prev and next must have the same shape; got {p.shape} and {n.shape}")
        return p, n, _mask(mask, "mask", p.shape)

    def _calc_into(
        self,
        prev: ArrayLike,
        next: ArrayLike,
        mask: Optional[ArrayLike],
        warm: bool,
        out: Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
    ) -> float:
        """:meth:`calc` for a sequence: warm-started (``warm``) from this
        estimator's own previous result, the result written into ``out`` = (u,
        v, quality: float32 (H, W); valid: bool (H, W)), C-contiguous views
        that are written in place. Returns the residual ratio. Saves the
        copies of :meth:`calc` (warm start in, four new arrays out)."""
        p, n, m = self._inputs(prev, next, mask)
        u, v, q, valid = out
        return float(self._impl.calc_into(p, n, m, warm, u, v, q, valid.view(np.uint8)))


def optical_flow(
    prev: ArrayLike,
    next: ArrayLike,
    method: str = DEFAULT_METHOD,
    options=None,
    mask: Optional[ArrayLike] = None,
    flow: Optional[Union[Flow, tuple]] = None,
    source_mask: Optional[ArrayLike] = None,
) -> Flow:
    """Displacement [px/frame] of the gas from ``prev`` to ``next``.

    Parameters
    ----------
    prev, next : array (H, W)
        Consecutive frames of one channel: radiance contrast or column density.
    method : str, default "fluid"
        ``"fluid"``, ``"horn_schunck"``, ``"lucas_kanade"``, ``"farneback"``,
        ``"dis"`` or ``"piv"`` (see the module documentation for when to use
        which).
    options : options object, optional
        ``METHODS[method]`` instance, e.g. ``FluidFlowOptions(alpha=0.2)``.
    mask : array (H, W) of bool, optional
        Gas mask (e.g. :func:`plume_mask`); vectors outside are invalid.
    flow : Flow or (u, v), optional
        Warm start.
    source_mask : array (H, W) of bool, optional
        Fluid method: where gas enters the image (the stack exit).

    Returns
    -------
    Flow

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> a = rng.random((64, 64)).astype(np.float32)
    >>> f = optical_flow(a, np.roll(a, 1, axis=1), method="horn_schunck")
    >>> round(float(np.median(f.u[16:-16, 16:-16])), 1)
    1.0
    """
    return FlowEstimator(method, options, source_mask).calc(prev, next, mask, flow)


@dataclass
class FlowSequence:
    """Displacements of consecutive frame pairs (pair k = frames k, k + 1).

    Attributes
    ----------
    u, v : ndarray (T - 1, H, W) float32
    quality : ndarray (T - 1, H, W) float32, or None
    valid : ndarray (T - 1, H, W) bool, or None
        None when the sequence was computed without them
        (:func:`optical_flow_sequence`'s ``keep_quality``).
    residual_ratio : ndarray (T - 1,)
    method : str
    """

    u: np.ndarray
    v: np.ndarray
    quality: Optional[np.ndarray]
    valid: Optional[np.ndarray]
    residual_ratio: np.ndarray
    method: str

    def __len__(self) -> int:
        return self.u.shape[0]

    def __getitem__(self, k: int) -> Flow:
        if self.quality is None or self.valid is None:
            raise ValueError(
                "this FlowSequence was computed with keep_quality=False: it holds u and v "
                "only (index them directly, or compute it with keep_quality=True)"
            )
        return Flow(
            self.u[k],
            self.v[k],
            self.quality[k],
            self.valid[k],
            float(self.residual_ratio[k]),
            self.method,
        )


def optical_flow_sequence(
    frames: ArrayLike,
    method: str = DEFAULT_METHOD,
    options=None,
    masks: Optional[ArrayLike] = None,
    source_mask: Optional[ArrayLike] = None,
    warm_start: bool = True,
    workers: int = 1,
    progress: Optional[Callable[[float], Optional[bool]]] = None,
    out: Optional[Tuple[np.ndarray, np.ndarray]] = None,
    keep_quality: bool = True,
) -> FlowSequence:
    """Displacements of every consecutive pair of a frame stack.

    Each pair starts from the previous pair's result (``warm_start``), which
    follows large and slowly changing motion beyond the pyramid's reach and
    lets the fluid method carry the flux further into featureless parts of
    the plume from one pair to the next.

    Parameters
    ----------
    frames : array (T, H, W)
        T >= 2 frames of one channel.
    method, options, source_mask
        As for :func:`optical_flow`.
    masks : array (T, H, W) or (H, W) of bool, optional
        Gas mask per frame (the first frame's of each pair is used) or one for
        all.
    warm_start : bool, default True
    workers : int, default 1
        Split the sequence into this many contiguous chunks processed in
        parallel, each on one engine thread (0 = one per core). On a
        recording this uses the cores better than splitting each frame pair
        across threads. Each chunk after the first starts
        ``WARM_UP_PAIRS`` pairs early (results discarded) so that its first
        kept pair is warm-started too.
    progress : callable(fraction) -> bool or None, optional
        Called after each pair (from the calling thread); returning False
        stops with qogi.Cancelled (Ctrl-C: KeyboardInterrupt).
    out : (u, v), optional
        C-contiguous float32 arrays (T - 1, H, W) the displacements are
        written into (the sequence's ``u`` and ``v`` are then these), e.g.
        the first T - 1 frames of (T, H, W) buffers that
        :func:`frame_velocity_in_place` turns into frame velocities.
    keep_quality : bool, default True
        False: the per-vector quality and validity are not kept (each
        worker writes them into one scratch frame; ``quality`` and
        ``valid`` are None): the sequence then takes 2 instead of 3.25
        float32 stacks of memory. The displacements are the same.

    Returns
    -------
    FlowSequence
    """
    stack = np.asarray(frames)
    if stack.ndim != 3 or stack.shape[0] < 2:
        raise ValueError(f"frames must be a (T, H, W) stack with T >= 2; got shape {stack.shape}")
    T, H, W = stack.shape
    mask_stack = None
    if masks is not None:
        mask_stack = np.asarray(masks)
        if mask_stack.shape == (H, W):
            mask_stack = np.broadcast_to(mask_stack, (T, H, W))
        elif mask_stack.shape != (T, H, W):
            raise ValueError(
                f"masks must have shape {(T, H, W)} or {(H, W)}; got {mask_stack.shape}"
            )
    if workers < 0:
        raise ValueError(f"workers must be >= 0 (0 = one per core); got {workers}")
    n_pairs = T - 1
    if workers == 0:
        workers = max(1, _engine.resolve_threads(0))
    workers = min(workers, n_pairs)
    if out is None:
        out_u = np.empty((n_pairs, H, W), np.float32)
        out_v = np.empty_like(out_u)
    else:
        out_u, out_v = out
        for name, a in (("u", out_u), ("v", out_v)):
            if (
                not isinstance(a, np.ndarray)
                or a.shape != (n_pairs, H, W)
                or a.dtype != np.float32
                or not a.flags.c_contiguous
            ):
                raise ValueError(
                    f"out's {name} must be a C-contiguous float32 array of shape "
                    f"{(n_pairs, H, W)}; got {getattr(a, 'dtype', type(a).__name__)} "
                    f"{np.shape(a)}"
                )
    out_q = np.empty_like(out_u) if keep_quality else None
    out_valid = np.empty((n_pairs, H, W), bool) if keep_quality else None
    ratio = np.empty(n_pairs)
    bounds = np.linspace(0, n_pairs, workers + 1).round().astype(int)
    estimators = [FlowEstimator(method, options, source_mask) for _ in range(workers)]
    done = [0]
    cancelled = [False]

    def run(chunk: int) -> None:
        est, first, stop = estimators[chunk], bounds[chunk], bounds[chunk + 1]
        start = max(0, first - WARM_UP_PAIRS) if (warm_start and chunk > 0) else first
        # The warm-up pairs' results (discarded) go to this chunk's own
        # frames, and so do quality and validity when they are not kept.
        scratch = (
            np.empty((H, W), np.float32),
            np.empty((H, W), np.float32),
            np.empty((H, W), np.float32),
            np.empty((H, W), bool),
        )
        for k in range(start, stop):
            if cancelled[0]:
                return
            m = None if mask_stack is None else mask_stack[k]
            if k < first:
                dst = scratch
            elif out_q is None or out_valid is None:
                dst = (out_u[k], out_v[k], scratch[2], scratch[3])
            else:
                dst = (out_u[k], out_v[k], out_q[k], out_valid[k])
            r = est._calc_into(stack[k], stack[k + 1], m, warm_start and k > start, dst)
            if k < first:
                continue
            ratio[k] = r
            done[0] += 1
            if workers == 1 and progress is not None and progress(done[0] / n_pairs) is False:
                cancelled[0] = True

    if workers == 1:
        run(0)
    else:
        import concurrent.futures as cf

        threads = get_num_threads()
        set_num_threads(1)  # one engine thread per chunk
        try:
            with cf.ThreadPoolExecutor(workers) as pool:
                futures = [pool.submit(run, c) for c in range(workers)]
                try:
                    while not all(f.done() for f in futures):
                        cf.wait(futures, timeout=0.1)
                        if (
                            progress is not None
                            and not cancelled[0]
                            and progress(done[0] / n_pairs) is False
                        ):
                            cancelled[0] = True
                except BaseException:  # Ctrl-C: let the workers stop early
                    cancelled[0] = True
                    raise
                for f in futures:
                    f.result()
        finally:
            set_num_threads(threads)
    if cancelled[0]:
        raise Cancelled("optical_flow_sequence cancelled by the progress callback")
    return FlowSequence(out_u, out_v, out_q, out_valid, ratio, method)


#: Pairs a parallel chunk starts early so that its first kept pair is warm.
WARM_UP_PAIRS = 2


def metres_per_second_per_pixel_per_frame(
    distance_m: float, ifov_rad: float, frame_rate_hz: float
) -> float:
    """Factor from px/frame to m/s: ``distance_m * ifov_rad * frame_rate_hz``.

    One pixel spans ``distance_m * ifov_rad`` metres in the plume plane
    (thesis eq. 7-11); one frame lasts ``1 / frame_rate_hz`` s.
    """
    return _engine.metres_per_second_per_pixel_per_frame(distance_m, ifov_rad, frame_rate_hz)


def to_metres_per_second(displacement, distance_m: float, ifov_rad: float, frame_rate_hz: float):
    """Displacement [px/frame] (array or scalar) to speed [m/s]."""
    k = metres_per_second_per_pixel_per_frame(distance_m, ifov_rad, frame_rate_hz)
    return (
        np.asarray(displacement, dtype=float) * k
        if np.ndim(displacement)
        else float(displacement) * k
    )


def _field(a, name: str) -> np.ndarray:
    arr = np.asarray(a)
    if arr.ndim != 2:
        raise ValueError(f"{name} must be 2-D; got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.float32)


def normalised_median_test(
    u: ArrayLike,
    v: ArrayLike,
    valid: Optional[ArrayLike] = None,
    threshold: float = 2.0,
    epsilon: float = 0.1,
    radius: int = 1,
) -> np.ndarray:
    """Outliers by the normalised median test (Westerweel & Scarano 2005).

    For each valid vector, ``|u0 - um| / (rm + epsilon) > threshold`` for u
    or v, with ``um`` the median of the valid neighbours within ``radius``
    (8 for radius 1) and ``rm`` the median of their ``|u_i - um|``.

    Parameters
    ----------
    u, v : array (H, W), px/frame
    valid : array (H, W) of bool, optional
        Vectors to test and to use as neighbours (default all).
    threshold : float, default 2
    epsilon : float, px/frame, default 0.1
    radius : int, default 1

    Returns
    -------
    ndarray (H, W) bool
        True where the vector is an outlier.
    """
    uu, vv = _field(u, "u"), _field(v, "v")
    k = np.ones(uu.shape, np.uint8) if valid is None else _mask(valid, "valid", uu.shape)
    opts = MedianTestOptions(threshold=threshold, epsilon=epsilon, radius=radius)
    return _engine.normalised_median_test(uu, vv, k, opts).astype(bool)


def replace_vectors(
    u: ArrayLike, v: ArrayLike, keep: ArrayLike, max_distance: int = 0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Replace the vectors not kept by the median of their kept neighbours.

    Grows inwards from the kept vectors, at most ``max_distance`` vectors
    (0 = until all are replaced).

    Returns
    -------
    (u, v, filled) : new arrays; ``filled`` (bool) marks the replaced vectors.
    """
    uu, vv = _field(u, "u"), _field(v, "v")
    if max_distance < 0:
        raise ValueError(f"max_distance must be >= 0 (0 = no limit); got {max_distance}")
    ru, rv, filled = _engine.replace_vectors(
        uu, vv, _mask(keep, "keep", uu.shape), int(max_distance)
    )
    return ru, rv, filled.astype(bool)


def validate(
    flow: Flow, threshold: float = 2.0, epsilon: float = 0.1, radius: int = 1, max_distance: int = 3
) -> tuple[Flow, np.ndarray]:
    """Median test, then replacement of the outliers.

    Returns a new Flow whose outliers are replaced (within ``max_distance``
    vectors of a valid one) and marked invalid, and the outlier mask.
    """
    out = normalised_median_test(flow.u, flow.v, flow.valid, threshold, epsilon, radius)
    keep = flow.valid & ~out
    u, v, _ = replace_vectors(flow.u, flow.v, keep, max_distance)
    # Only the outliers change; other invalid vectors stay as they were.
    u = np.where(out, u, flow.u)
    v = np.where(out, v, flow.v)
    return Flow(u, v, flow.quality.copy(), keep, flow.residual_ratio, flow.method), out


def temporal_filter(
    u,
    v=None,
    valid=None,
    window: int = 5,
    statistic: str = "median",
    min_valid_fraction: float = 0.5,
):
    """Filter vector fields over time, pixel by pixel.

    Vector t becomes the mean or median of the valid vectors at that pixel in
    frames ``t - window // 2 ... t + window // 2`` (shortened at the ends).

    Parameters
    ----------
    u : array (T, H, W) or FlowSequence
    v, valid : arrays (T, H, W), when ``u`` is an array (valid default all)
    window : int, odd, default 5
    statistic : "median" or "mean"
    min_valid_fraction : float, default 0.5
        Share of the window's frames that must be valid at the pixel.

    Returns
    -------
    (u, v, valid) arrays, or a FlowSequence when given one.
    """
    seq = u if isinstance(u, FlowSequence) else None
    if seq is not None:
        u, v, valid = seq.u, seq.v, seq.valid
    uu = np.ascontiguousarray(u, dtype=np.float32)
    vv = np.ascontiguousarray(v, dtype=np.float32)
    if uu.ndim != 3 or vv.shape != uu.shape:
        raise ValueError(
            f"u and v must be (T, H, W) stacks of one shape; got {uu.shape} and {vv.shape}"
        )
    kk = (
        np.ones(uu.shape, np.uint8)
        if valid is None
        else np.ascontiguousarray(np.asarray(valid) != 0, dtype=np.uint8)
    )
    if kk.shape != uu.shape:
        raise ValueError(f"valid must have shape {uu.shape}; got {kk.shape}")
    try:
        stat = {"median": _engine.TemporalStatistic.median, "mean": _engine.TemporalStatistic.mean}[
            statistic
        ]
    except KeyError:
        raise ValueError(f"statistic must be 'median' or 'mean'; got {statistic!r}") from None
    opts = TemporalFilterOptions(
        window=window, statistic=stat, min_valid_fraction=min_valid_fraction
    )
    fu, fv, fk = _engine.temporal_filter(uu, vv, kk, opts)
    if seq is not None:
        quality = None if seq.quality is None else seq.quality.copy()
        return FlowSequence(fu, fv, quality, fk.astype(bool), seq.residual_ratio.copy(), seq.method)
    return fu, fv, fk.astype(bool)


def invert_displacement(
    u: ArrayLike, v: ArrayLike, iterations: int = 10
) -> tuple[np.ndarray, np.ndarray]:
    """Backward displacement of a forward map ``x -> x + w(x)``.

    Returns ``b`` with ``y + w(y) = x`` for ``y = x + b(x)``, by the fixed-point
    iteration ``y = x - w(y)`` (``w`` sampled bilinearly; at most
    ``iterations`` sweeps, fewer once the mean change is below 1e-4 px;
    converges where the map does not fold, ``|grad w| < 1``).

    Parameters
    ----------
    u, v : array (H, W), px/frame
        Forward displacement of the pixels of the first frame.

    Returns
    -------
    (bu, bv) : ndarray (H, W) float32, px/frame
        Where the gas at each pixel of the second frame was in the first,
        relative to that pixel.
    """
    if iterations < 1:
        raise ValueError(f"iterations must be >= 1; got {iterations}")
    return _engine.invert_displacement(_field(u, "u"), _field(v, "v"), int(iterations))


def frame_velocity(u, v=None) -> tuple[np.ndarray, np.ndarray]:
    """Velocity [px/frame] at the time of each frame of a sequence.

    Pair k's forward displacement ``w_k`` (what every method returns) is the
    mean velocity along the path of the gas from frame k to k + 1, not the
    velocity at frame k: where the gas accelerates, they differ by half the
    acceleration times the frame interval (e.g. 0.3 m/s, 50 %, at 15 Hz just
    above a laminar exit). The central difference of the trajectory through
    each pixel at frame t,

        v_t(x) = (w_t(x) - b_t(x)) / 2,

    with ``b_t`` the inverse of ``w_{t-1}`` (:func:`invert_displacement`), is
    exact for constant acceleration. Multiply by the column of frame t for the
    flux at frame t. The first frame gets ``w_0``, the last ``-b_{T-1}``.

    Parameters
    ----------
    u : array (T - 1, H, W) or FlowSequence
        Forward displacements of the T - 1 consecutive pairs [px/frame].
    v : array (T - 1, H, W), when ``u`` is an array

    Returns
    -------
    (u, v) : ndarray (T, H, W) float32, px/frame
    """
    if isinstance(u, FlowSequence):
        u, v = u.u, u.v
    if v is None:
        raise ValueError("frame_velocity needs v (or a FlowSequence as u)")
    uu = np.ascontiguousarray(u, dtype=np.float32)
    vv = np.ascontiguousarray(v, dtype=np.float32)
    if uu.ndim != 3 or vv.shape != uu.shape or uu.shape[0] < 1:
        raise ValueError(
            f"u and v must be (T-1, H, W) stacks of one shape with T-1 >= 1; "
            f"got {uu.shape} and {vv.shape}"
        )
    return _engine.frame_velocity(uu, vv)


#: Frames per call of :func:`frame_velocity_in_place` (its scratch: two
#: such stacks and one frame more).
FRAME_VELOCITY_CHUNK = 16


def frame_velocity_in_place(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`frame_velocity` written over its input: ``u``, ``v`` (T, H, W)
    float32, C-contiguous, whose first T - 1 frames hold the pairs'
    displacements [px/frame] (e.g. :func:`optical_flow_sequence` with ``out``
    the first T - 1 frames), become the velocity at each of the T frames.

    The same values as :func:`frame_velocity` (each frame's velocity is made
    from pairs t - 1 and t alone), computed from the last frame backwards
    :data:`FRAME_VELOCITY_CHUNK` frames at a time, so that no second pair of
    (T, H, W) stacks is held: frame t's velocity overwrites pair t, which no
    earlier frame needs. Returns ``(u, v)``.
    """
    for name, arr in (("u", u), ("v", v)):
        if not (
            isinstance(arr, np.ndarray)
            and arr.ndim == 3
            and arr.shape[0] >= 2
            and arr.dtype == np.float32
            and arr.flags.c_contiguous
            and arr.flags.writeable
        ):
            raise ValueError(
                f"{name} must be a writeable C-contiguous float32 (T, H, W) array with T >= 2 "
                f"(T - 1 pairs' displacements, then a frame of room); got "
                f"{getattr(arr, 'dtype', type(arr).__name__)} {np.shape(arr)}"
            )
    if v.shape != u.shape:
        raise ValueError(f"u and v must have one shape; got {u.shape} and {v.shape}")
    T = u.shape[0]
    b = T
    while b > 0:
        # Frames a ... b - 1 need pairs a - 1 ... b - 1 (the last frame pair T - 2 only).
        a = max(0, b - FRAME_VELOCITY_CHUNK)
        lo, hi = max(0, a - 1), min(b, T - 1)
        fu, fv = _engine.frame_velocity(u[lo:hi], v[lo:hi])
        u[a:b] = fu[a - lo : b - lo]
        v[a:b] = fv[a - lo : b - lo]
        b = a
    return u, v


# -- flux level from the transport of the line-integrated column -------------

#: Directions a plume may be analysed along by :func:`transport_flux`.
AXES = ("up", "down", "left", "right")


def _check_axis(axis: str) -> None:
    if axis not in AXES:
        raise ValueError(
            f"axis must be one of {AXES} (the direction the plume leaves the "
            f"source in the image); got {axis!r}"
        )


@dataclass
class TransportFlux:
    """Time-averaged transport of a plume along one image axis
    (:func:`transport_flux`). Arrays are indexed by the row (``axis`` "up" or
    "down") or the column ("left", "right") of the frames.

    Attributes
    ----------
    flux : ndarray
        Time-averaged flux through each line across the axis, towards
        ``axis``: the sum over the line's pixels of frame value x velocity
        [frame unit x px/frame]. NaN in the source and beyond the last line
        with gas. For kg/s with column density in kg/m2, multiply by the
        pixel size [m] squared and the frame rate [1/s].
    line_column : ndarray
        Time-averaged sum of the frames over each line's pixels [frame unit].
    velocity : ndarray
        ``flux / line_column``: the time-averaged mass-weighted velocity
        towards ``axis`` [px/frame].
    displacement : ndarray
        The steady displacement of each line's material level over one frame
        [px/frame]; NaN where it was not solved (the gas crossing the line
        within one frame came from the source).
    axis : str
    unexplained : ndarray
        How little of each solved level's column the time of flight
        explains: the fit's residual (after each pair's outflow) squared over
        the squared temporal anomaly of the column beyond the level, summed
        over the pairs. 0 for structures carried unchanged; near 1 or above
        when the displacement explains no more than the column's mean (the
        structures changed beyond recognition between frames, or moved
        further than the fit follows). NaN where not solved.
    """

    flux: np.ndarray
    line_column: np.ndarray
    velocity: np.ndarray
    displacement: np.ndarray
    axis: str
    unexplained: Optional[np.ndarray] = None

    def lines(self, sl: slice, scale: float = 1.0) -> TransportFlux:
        """The lines ``sl`` (rows for "up"/"down", columns otherwise) of this
        result, its flux and line column multiplied by ``scale`` (e.g. to the
        units of a rescaled field); velocities and displacements unchanged."""
        return TransportFlux(
            self.flux[sl] * scale,
            self.line_column[sl] * scale,
            self.velocity[sl],
            self.displacement[sl],
            self.axis,
            None if self.unexplained is None else self.unexplained[sl],
        )


#: Seconds per time-of-flight fit of the flux level in the pipeline
#: (:func:`transport_flux`'s ``window`` at the recording's frame rate): chosen
#: on the GF320 lab release's exact columns at 2 and 20 g/h, seeds 0-3
#: (10 s at 15 Hz, surfaces 6-10 cm): the mean over surfaces and runs read
#: 0.853 of the truth with one fit over the record, and 1.036, 1.005, 0.989,
#: 0.980, 0.966 with windows of 10, 15, 18, 20, 23 frames (0.67-1.5 s; the
#: spread over runs 0.073 -> 0.033-0.040); docs/validation.md.
TRANSPORT_WINDOW_S = 1.0


def transport_flux(
    frames: ArrayLike,
    axis: str = "up",
    source_index: Optional[float] = None,
    intervals: Optional[ArrayLike] = None,
    window: int = 0,
    mask: Optional[ArrayLike] = None,
) -> TransportFlux:
    """Time-averaged flux of a plume along an image axis, from the transport
    of its line-integrated column (time of flight of its structures).

    Summed over the lines across the axis, the continuity equation becomes
    one-dimensional and exact: with ``C_t(y)`` the column summed over the
    lines above level ``y`` (towards ``axis``), the gas that crosses level
    ``k`` during frame t came from level ``k + d_k``:

        C_t(k + d_k) = C_{t+1}(k) + O_t,

    ``O_t`` being what left through the far edge of the frame. A steady
    plume fits any flux level (mass conservation does not fix it); the
    structures carried along it do: over many frames, one steady
    displacement ``d_k`` per level and one outflow per frame are solved by
    Gauss-Newton in the least-squares sense. The time-averaged flux through
    level k is then ``mean_t (C_t(k + d_k) - C_t(k))``; at levels whose
    displacement reaches into the source (near the exit at low frame rates)
    it follows from the nearest solved level by the exact mass balance of
    the lines between them. This is the time-averaged flux of the plume, not
    of each frame: where the velocity at a level fluctuates together with
    the column, their covariance is not seen.

    Requires that the gas leaves only through the far edge (not the sides)
    and the whole plume width is in the frame. The frames must be
    proportional to column density (zero without gas). Computed by the
    engine (``engine/flux/transport_flux.h``; released GIL, Ctrl-C stops it).

    Parameters
    ----------
    frames : array (T, H, W)
        T >= 3 column-density frames (any linear unit).
    axis : {"up", "down", "left", "right"}
        Direction of the plume's transport in the image.
    source_index : float, optional
        Row ("up", "down") or column of the source's exit: lines beyond it
        (inside the stack) are the source. None: the gas enters across the
        near edge of the frame.
    intervals : array (T - 1,), optional
        The interval between consecutive frames in units of the nominal frame
        interval (from their time stamps: 2 where a frame was dropped);
        default all 1. Displacements, velocities and fluxes are then per
        nominal interval, and the level's displacement in pair t is
        ``intervals[t] x d_k``.
    window : int, default 0
        Frame pairs per time-of-flight fit: 0, one fit (one steady
        displacement per level) over the whole record; else >= 4, the pairs
        split into ``round(pairs / window)`` windows of nearly equal length,
        each fitted on its own, and the flux is the mass crossing each level
        summed over the windows per nominal interval. Where the gas's speed
        changes over the record (a lab's draft), its column piles up where it
        slows, and one steady displacement reads the flux low (0.74-1.02 of
        the truth, 0.85 on average, on the GF320 lab release's exact columns
        over 10 s); windows shorter than the speed's changes follow them
        (each window's fit starts from the whole record's). Very short
        windows read high
        (:data:`TRANSPORT_WINDOW_S`, docs/velocimetry.md).
    mask : array (H, W) of bool, optional
        Only these pixels of each line are summed (e.g. :func:`transport_band`):
        the same result as ``frames * mask`` without that second stack.

    Returns
    -------
    TransportFlux
    """
    _check_axis(axis)
    stack = np.ascontiguousarray(frames, dtype=np.float32)
    if stack.ndim != 3 or stack.shape[0] < 3:
        raise ValueError(f"frames must be a (T, H, W) stack with T >= 3; got shape {stack.shape}")
    # The engine refuses frames that are not finite ("frames must be finite
    # (replace NaN pixels by 0 or an estimate)") without a (T, H, W) mask.
    T = stack.shape[0]
    r = None if intervals is None else np.asarray(intervals, dtype=float)
    if r is not None and (r.shape != (T - 1,) or not np.all(np.isfinite(r) & (r > 0))):
        raise ValueError(f"intervals must be {T - 1} positive frame intervals; got shape {r.shape}")
    m = None
    if mask is not None:
        m = np.asarray(mask)
        if m.shape != stack.shape[1:]:
            raise ValueError(f"mask must have the frames' shape {stack.shape[1:]}; got {m.shape}")
        m = np.ascontiguousarray(m != 0, dtype=np.uint8)
    # The engine checks source_index (a row or column inside the frame).
    flux, line_column, velocity, displacement, unexplained = _engine.transport_flux(
        stack,
        axis,
        None if source_index is None else float(source_index),
        r,
        int(window),
        mask=m,
    )
    return TransportFlux(flux, line_column, velocity, displacement, axis, unexplained)


def transport_band(
    mean_field: ArrayLike,
    axis: str = "up",
    z: float = 4.0,
    neighbour_lines: int = 5,
    min_margin_px: int = 8,
) -> np.ndarray:
    """The part of each line across ``axis`` that holds the plume: a static
    mask for the frames given to :func:`transport_flux`.

    The transport's line sums run across the whole frame; noise that is
    common to a line (a background estimated per frame from strips at the
    frame's edges errs by the same amount all along a line) then enters them
    multiplied by the line's length, and in the time-of-flight fit, like any
    noise in a regressor, it draws the displacement towards zero
    (errors-in-variables attenuation): the GF320 lab release at 2 g/h read
    its flux level 20-27 % low that way, at 200 g/h a few %. Summing only the
    plume's part of each line keeps the gas and leaves out most of that
    noise.

    A pixel is significant where the time-averaged field exceeds its median
    by ``z`` times its noise (1.4826 x the median absolute deviation of the
    averaged field, most of which holds no gas) and so does a neighbour
    along its line. A
    line's band runs from the first to the last significant pixel of the
    lines within ``neighbour_lines`` of it,
    widened on each side by its own width, at least ``min_margin_px`` (the
    plume's meander and faint edges); a line without one takes the nearest
    line's band; without any significant pixel the whole frame is kept.

    Parameters
    ----------
    mean_field : array (H, W)
        Time average of the column (or proxy) frames, gas positive.
    axis : {"up", "down", "left", "right"}
        As for :func:`transport_flux` (lines are rows for up and down).
    z : float
        Significance in noise units.
    neighbour_lines : int
    min_margin_px : int

    Returns
    -------
    ndarray (H, W) bool
    """
    _check_axis(axis)
    m = np.asarray(mean_field, dtype=float)
    if m.ndim != 2:
        raise ValueError(f"mean_field must be a 2-D (H, W) image; got shape {m.shape}")
    view = m if axis in ("up", "down") else m.T  # (lines, across)
    finite = np.where(np.isfinite(view), view, 0.0)
    floor = float(np.median(finite))
    noise = 1.4826 * float(np.median(np.abs(finite - floor)))
    band = np.ones(view.shape, bool)
    if not noise > 0:
        return band if axis in ("up", "down") else band.T
    # Above the field's own floor (its median, most of it holds no gas): a
    # background offset by a constant does not widen the band.
    sig = finite - floor > z * noise
    # Isolated pixels (noise) do not stretch a band: a significant pixel
    # needs a significant neighbour along its line.
    pair = sig[:, 1:] & sig[:, :-1]
    sig = np.zeros_like(sig)
    sig[:, 1:] |= pair
    sig[:, :-1] |= pair
    n_lines, width = view.shape
    k = int(max(0, neighbour_lines))
    seen = np.flatnonzero(sig.any(axis=1))
    if seen.size == 0:
        return band if axis in ("up", "down") else band.T
    lo = np.full(n_lines, -1)
    hi = np.full(n_lines, -1)
    for i in range(n_lines):
        cols = np.flatnonzero(sig[max(0, i - k) : i + k + 1].any(axis=0))
        if cols.size:
            lo[i], hi[i] = cols[0], cols[-1]
    have = np.flatnonzero(lo >= 0)
    nearest = have[np.clip(np.searchsorted(have, np.arange(n_lines)), 0, have.size - 1)]
    # The nearer of the two neighbours in `have` around each line.
    prev = have[np.clip(np.searchsorted(have, np.arange(n_lines)) - 1, 0, have.size - 1)]
    use = np.where(
        np.abs(prev - np.arange(n_lines)) <= np.abs(nearest - np.arange(n_lines)), prev, nearest
    )
    lo, hi = lo[use], hi[use]
    margin = np.maximum(hi - lo + 1, int(min_margin_px))
    start = np.clip(lo - margin, 0, width)
    stop = np.clip(hi + margin + 1, 0, width)
    across = np.arange(width)[None, :]
    band = (across >= start[:, None]) & (across < stop[:, None])
    return band if axis in ("up", "down") else band.T


def typical_displacement(frames: ArrayLike, axis: str = "up", max_px: int = 16) -> float:
    """Typical displacement [px/frame] of a plume's structures along ``axis``:
    where the correlation of consecutive frames' line sums (their temporal
    anomalies, over all lines) peaks among shifts 0 ... ``max_px`` (sub-pixel
    by a parabola through the peak). NaN when the peak is at ``max_px`` (the
    plume moves faster) or the frames do not change.

    Used to choose how many frames apart the pairs of a sequence are
    (``pair_stride`` of the pipeline): at 100 Hz a lab plume moves ~1 px per
    frame, below what a flow resolves well relative to its own error."""
    _check_axis(axis)
    stack = np.asarray(frames, dtype=np.float32)
    if stack.ndim != 3 or stack.shape[0] < 3:
        raise ValueError(f"frames must be a (T, H, W) stack with T >= 3; got shape {stack.shape}")
    if max_px < 2:
        raise ValueError(f"max_px must be >= 2; got {max_px}")
    return float(_engine.typical_displacement(np.ascontiguousarray(stack), axis, int(max_px)))


def interpolate_frame_velocity(
    u: np.ndarray, v: np.ndarray, stride: int, frames: int
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity [px/frame] at every one of ``frames`` frames from the velocity
    at every ``stride``-th (``u``, ``v``: (ceil(frames / stride), H, W) in px
    per ``stride`` frames, e.g. :func:`frame_velocity` of the sequence of
    frames 0, stride, 2 stride, ...): linear in time between them, held after
    the last. Returns float32 (frames, H, W) arrays."""
    if stride < 1:
        raise ValueError(f"stride must be >= 1; got {stride}")
    n = u.shape[0]
    if v.shape != u.shape or n != -(-frames // stride):
        raise ValueError(
            f"u and v must hold ceil({frames} / {stride}) = {-(-frames // stride)} "
            f"frames of one shape; got {u.shape} and {v.shape}"
        )
    inv = np.float32(1.0 / stride)
    out = []
    for src in (u, v):
        dst = np.empty((frames,) + src.shape[1:], np.float32)
        for t in range(frames):
            i, r = divmod(t, stride)
            if r == 0 or i + 1 >= n:
                np.multiply(src[min(i, n - 1)], inv, out=dst[t])
            else:
                w = np.float32(r / stride)
                np.multiply(src[i], (1 - w) * inv, out=dst[t])
                dst[t] += src[i + 1] * (w * inv)
        out.append(dst)
    return out[0], out[1]


def calibrate_flux_level(
    seq: Optional[FlowSequence],
    frames: ArrayLike,
    axis: str = "up",
    source_index: Optional[float] = None,
    smooth_px: float = 2.0,
    min_fraction: float = 0.05,
    max_factor: float = 2.5,
    transport: Optional[TransportFlux] = None,
    frame_velocities: Optional[tuple] = None,
    max_reversed: float = 0.1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Velocity at each frame time (:func:`frame_velocity`), rescaled line by
    line so that its time-averaged flux along ``axis`` equals the transport
    flux of the frames (:func:`transport_flux`).

    The 2-D flow (e.g. the fluid method) supplies the shape of the velocity
    field in space and time; the flux *level*, which mass conservation
    leaves to the regulariser in a steady plume, is taken from the time of
    flight of the plume's structures. Per line across the axis the factor is

        s = transport flux / mean_t sum_line frame_t x v_t,

    with ``v_t`` the velocity along the axis at frame t
    (:func:`frame_velocity`), smoothed along the axis over ``smooth_px``
    (Gaussian sigma) on the lines carrying at least ``min_fraction`` of the
    largest flux, and extended to the others from the nearest such line.
    Both components of the frame velocity are multiplied by it (the factors
    from the engine, ``engine/flux/flux_level.h``). (Scaling the
    pairs' displacements instead would not do: at 15 Hz the gas crosses
    ~20 lines per frame, and the inversion in :func:`frame_velocity` mixes
    the factors of lines far apart.)

    A line's factor is used only within [1 / ``max_factor``, ``max_factor``]
    (the fluid flow alone reads 8-33 % low on the lab plumes, factors up to
    ~2.3 on the 100 Hz stack release): outside it the flow does not measure
    the transport there (e.g. a plume
    carried by wind tens of pixels per frame, beyond what the flow can
    follow, or a flow running against the transport), and only when at most
    ``max_reversed`` of the flow's frame-by-frame flux through the line
    (|flux| summed over the frames) runs against the transport (a flow that
    lost a fast crosswind for a stretch of the record and reads it backwards
    there, while its time average lands within the factors). A line that
    carries the transport flux without a usable factor takes the transport's
    own velocity (its scale NaN), not a neighbour's factor: near a source
    in a crosswind the fluid flow ramps up from zero over tens of pixels
    while the gas crosses at the wind's speed, and the neighbour's factor
    read the first surface 62 % low (the operating envelope's +20 K, 2 m/s
    cell, seed 0; -2.6 % with the transport's velocity). When fewer than half
    of the lines that carry the transport flux have a usable factor, the flow
    is not used at all: the velocity is the transport's own, the time-averaged
    mass-weighted velocity of each line (:attr:`TransportFlux.velocity`),
    along the axis at every pixel and frame, and ``scale`` is all NaN.

    Parameters
    ----------
    seq : FlowSequence or None
        Displacements of the T - 1 pairs of ``frames`` (None with
        ``frame_velocities`` given).
    frames : array (T, H, W)
        The column-density frames the sequence was computed from.
    axis, source_index
        As for :func:`transport_flux`.
    smooth_px : float, default 2
    min_fraction : float, default 0.05
    max_factor : float, default 2.5
    transport : TransportFlux, optional
        The transport flux of the frames' lines (in the frames' units), e.g.
        measured along a longer stretch of the plume than the frames hold
        (:meth:`TransportFlux.lines` of a larger field's): the structures
        beyond the frames constrain the level too (on the synthetic M150
        release, 2 s records, the transport along the whole image reads
        0.83-1.06 of the truth where only the flow's part read 0.72-1.09).
        Default: :func:`transport_flux` of ``frames``.
    frame_velocities : (u, v), optional
        The velocity at every frame of ``frames`` [px/frame], (T, H, W) each,
        e.g. :func:`interpolate_frame_velocity` of a sequence of every n-th
        frame; they are scaled in place (and where the flow is not used,
        overwritten by the transport's velocity: no second pair of stacks).
        Default: :func:`frame_velocity` of ``seq`` (then ``seq`` may be None
        with them given).

    Returns
    -------
    (u, v, scale)
        Velocity at the T frame times [px/frame], (T, H, W) float32, and the
        factor per line (rows for "up" and "down", columns otherwise; NaN on
        the lines given the transport's velocity, all NaN when the transport
        velocity replaced the flow).
    """
    _check_axis(axis)
    stack = np.asarray(frames, dtype=np.float32)
    T = stack.shape[0] if stack.ndim == 3 else 0
    if frame_velocities is not None:
        fu, fv = frame_velocities
        if stack.ndim != 3 or fu.shape != stack.shape or fv.shape != stack.shape:
            raise ValueError(
                f"frame_velocities must be two arrays of the frames' shape "
                f"{stack.shape}; got {np.shape(fu)} and {np.shape(fv)}"
            )
    elif seq is None:
        raise ValueError("calibrate_flux_level needs seq, or frame_velocities with it None")
    elif stack.ndim != 3 or seq.u.shape != (T - 1,) + stack.shape[1:]:
        raise ValueError(
            f"frames must be the (T, H, W) stack of the sequence's T - 1 = "
            f"{seq.u.shape[0]} pairs of {seq.u.shape[1:]} frames; got shape "
            f"{stack.shape}"
        )
    if not smooth_px >= 0:
        raise ValueError(f"smooth_px must be >= 0; got {smooth_px}")
    if not 0 < min_fraction < 1:
        raise ValueError(f"min_fraction must be in (0, 1); got {min_fraction}")
    if transport is None:
        tf = transport_flux(stack, axis, source_index)
    else:
        n_lines = stack.shape[1] if axis in ("up", "down") else stack.shape[2]
        if transport.axis != axis or len(transport.flux) != n_lines:
            raise ValueError(
                f"transport must be along {axis!r} with one value per line of the "
                f"frames ({n_lines}); got {transport.axis!r} with "
                f"{len(transport.flux)}"
            )
        tf = transport
    if not max_factor > 1:
        raise ValueError(f"max_factor must be > 1; got {max_factor}")
    if not 0 < max_reversed <= 1:
        raise ValueError(f"max_reversed must be in (0, 1]; got {max_reversed}")
    if frame_velocities is None:
        assert seq is not None  # checked above
        fu, fv = frame_velocity(seq)
    scale, _flow_used = _engine.flux_level_scale(
        np.ascontiguousarray(stack),
        np.ascontiguousarray(fu, dtype=np.float32),
        np.ascontiguousarray(fv, dtype=np.float32),
        np.asarray(tf.flux, dtype=float),
        axis,
        float(smooth_px),
        float(min_fraction),
        float(max_factor),
        float(max_reversed),
    )
    # In place (the engine's): lines with a factor scaled, the others (a
    # carrying line the flow does not measure, or every line when the flow
    # was not used) given the transport's line velocity.
    work = [
        a
        if a.dtype == np.float32 and a.flags.c_contiguous and a.flags.writeable
        else np.ascontiguousarray(a, dtype=np.float32)
        for a in (fu, fv)
    ]
    _engine.apply_flux_level(
        work[0],
        work[1],
        np.ascontiguousarray(scale, dtype=np.float32),
        np.asarray(tf.velocity, dtype=float),
        np.asarray(tf.line_column, dtype=float),
        axis,
    )
    if frame_velocities is None:
        return work[0], work[1], scale
    for given, done in zip((fu, fv), work):
        if done is not given:
            given[...] = done
    return fu, fv, scale


def _transport_velocity(tf: TransportFlux, shape: tuple) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) [px/frame], (T, H, W) float32: each line's time-averaged
    transport velocity along the axis (extended to lines without one from the
    nearest line that has one), the same at every pixel of the line and frame."""
    T, H, W = shape
    return _engine.transport_velocity(
        np.asarray(tf.velocity, dtype=float),
        np.asarray(tf.line_column, dtype=float),
        tf.axis,
        T,
        H,
        W,
    )


def plume_frame_velocity(
    frames: ArrayLike,
    axis: str = "up",
    source_index: Optional[float] = None,
    method: str = DEFAULT_METHOD,
    options=None,
    masks: Optional[ArrayLike] = None,
    source_mask: Optional[ArrayLike] = None,
    flux_level: bool = True,
    workers: int = 1,
    progress: Optional[Callable[[float], Optional[bool]]] = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Velocity of a plume at each frame time, for the flux through a surface.

    The recommended chain on a recording's column-density frames:
    :func:`optical_flow_sequence` (warm-started, ``method``), the velocity at
    the frame times (:func:`frame_velocity`), and, with ``flux_level``, the
    flux level from the transport of the line-integrated column
    (:func:`calibrate_flux_level`). The flux at frame t through a surface is
    then frame t's column times the returned velocity's normal component.

    Parameters
    ----------
    frames : array (T, H, W)
        T >= 3 column-density frames (zero without gas).
    axis, source_index
        The plume's direction of transport in the image and the row (column)
        of its source, as for :func:`transport_flux`.
    method, options, masks, source_mask, workers, progress
        As for :func:`optical_flow_sequence`.
    flux_level : bool, default True
        Take the flux level from :func:`calibrate_flux_level`. Needs the
        whole plume width in the frame and the gas leaving through the far
        edge only; otherwise give False (the flow's own level).

    Returns
    -------
    (u, v) : ndarray (T, H, W) float32, px/frame
    """
    seq = optical_flow_sequence(
        frames,
        method=method,
        options=options,
        masks=masks,
        source_mask=source_mask,
        warm_start=True,
        workers=workers,
        progress=progress,
    )
    if not flux_level:
        return frame_velocity(seq)
    u, v, _ = calibrate_flux_level(seq, frames, axis, source_index)
    return u, v


def plume_mask(
    density: ArrayLike,
    threshold: float = 0.0,
    relative_threshold: float = 0.1,
    open_radius: int = 1,
    close_radius: int = 2,
    min_area: int = 20,
    dilate_radius: int = 2,
) -> np.ndarray:
    """Gas mask of a column-density (or contrast) map.

    Gas where ``density >= max(threshold, relative_threshold * p99)`` (p99 the
    frame's 99th percentile), then a morphological opening (removes noise
    specks), closing (fills holes), removal of regions smaller than
    ``min_area`` px and a dilation (keeps the plume's textured edge).

    Returns
    -------
    ndarray (H, W) bool
    """
    d = _frame(density, "density")
    opts = PlumeMaskOptions(
        threshold=threshold,
        relative_threshold=relative_threshold,
        open_radius=open_radius,
        close_radius=close_radius,
        min_area=min_area,
        dilate_radius=dilate_radius,
    )
    return _engine.plume_mask(d, opts).astype(bool)


def restrict_to_mask(flow: Flow, mask: ArrayLike) -> Flow:
    """A copy of ``flow`` whose vectors outside ``mask`` are invalid."""
    m = np.asarray(mask, dtype=bool)
    if m.shape != flow.valid.shape:
        raise ValueError(f"mask must have the flow's shape {flow.valid.shape}; got {m.shape}")
    return Flow(
        flow.u.copy(),
        flow.v.copy(),
        flow.quality.copy(),
        flow.valid & m,
        flow.residual_ratio,
        flow.method,
    )


def set_num_threads(num_threads: int) -> None:
    """Threads used by the velocimetry engine (0 = all cores)."""
    _engine.set_num_threads(int(num_threads))


def get_num_threads() -> int:
    """Threads used by the velocimetry engine."""
    return _engine.get_num_threads()
