"""Stage 1b, alignment: the frames brought to a common geometry and a common time.

Two things a real camera does that the later stages assume it does not:

* **A vibrating tripod** moves the whole image by fractions of a pixel
  (1-4 Hz, 0.1-0.5 px rms). Each frame's rigid motion (shift and small
  rotation) is measured against the static scene (the median of the run's
  sampled frames) by robust registration in the engine
  (:class:`qogi._engine.FrameRegistration`: Tukey-weighted Gauss-Newton, the
  moving gas left out by its weights) and the frame is resampled back before
  the background and the flow see it. Only the directions the scene's texture
  fixes are corrected (a sky graded only vertically fixes no horizontal
  shift, and there a horizontal shift changes nothing either). Off when the
  measured jitter is below :data:`JITTER_NEGLIGIBLE_PX` (a still camera's
  run is unchanged, bit for bit).
* **A filter wheel** sees channel k at its own time, ``offset_k`` from the
  turn's time (``rec.attrs["channel_time_offset_s"]``, from the Telops reader
  or the simulator). The gas's motion over a turn is measured with the
  optical flow between the neighbouring turns of one channel, and each
  channel's contrast against the static scene is moved back along it by
  ``offset_k`` (:func:`qogi._engine.warp_along_flow`), so that the
  multichannel inversion combines the channels at one instant.

Both replace :attr:`RunState.rec` by a view whose frames are corrected as
they are read (and the sampled frames likewise); ``Result.info`` records
``stabilisation`` and ``channel_timing``; ``jitter-uncorrected`` and
``jitter-residual`` warnings say when the correction fell short.
"""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

import numpy as np

from .. import _engine
from ..io.recording import Recording
from ..measure.velocimetry import FlowEstimator
from .state import RunState

__all__ = [
    "prepare",
    "JITTER_NEGLIGIBLE_PX",
    "JITTER_RESIDUAL_PX",
    "PRECISION_PX",
    "JITTER_MAX_PX",
]

#: Measured jitter [px rms] below which frames are left as they are.
JITTER_NEGLIGIBLE_PX = 0.05
#: A direction (dx, dy, the rotation at the image corner) is corrected only
#: when the scene's texture fixes it to this 1-sigma precision per frame [px].
PRECISION_PX = 0.02
#: Jitter left after correction [px rms] above which ``jitter-residual`` is raised.
JITTER_RESIDUAL_PX = 0.1
#: A frame moved by more than this [px] is put back, but its edges are then
#: filled by repeating the border over that width (``jitter-uncorrected``).
JITTER_MAX_PX = 4.0
#: Put back by the measured motion, the static scene's change from its
#: reference beyond the noise must fall below this fraction of what it was (else the
#: "motion" is the gas's, not the camera's).
STATIC_GAIN = 0.8
#: Filter-wheel timing is corrected only on runs of at least this many turns
#: (the static scene is their median; a 6-turn run's still holds the gas, and
#: its correction read a rate -61 % off the same run's HDF5 twin).
MIN_TURNS = 10
#: Frames sampled over the run to build the reference and measure the jitter.
SAMPLE_FRAMES = 50


def prepare(run: RunState) -> None:
    """Measures the run's jitter and channel timing and, where they matter,
    sets :attr:`RunState.rec` (and the sampled frames) to corrected views."""
    if run.cfg.methods.truth_columns:
        return
    samples = run.sample_frames
    if samples is None:
        use = list(run.frames)[:: max(1, len(run.frames) // SAMPLE_FRAMES)][:SAMPLE_FRAMES]
        samples = np.asarray([run.rec.frame(f, quantity="radiance") for f in use], np.float64)
    stab = _stabilisation(run, samples)
    if stab is not None:
        run.rec = _view(run.rec, _StabilisedFrames(run.rec, stab))
        if run.sample_frames is not None:
            run.sample_frames = np.asarray(
                [stab.warp(f.astype(np.float32)) for f in run.sample_frames], np.float64
            )
        samples = np.asarray([stab.warp(f.astype(np.float32)) for f in samples], np.float64)
    timing = _channel_timing(run, samples)
    if timing is not None:
        run.rec = _view(run.rec, _CommonTimeFrames(run.rec, timing))
        if run.sample_frames is not None:
            # The sampled frames are spread over the run: their correction
            # reads each one's neighbours.
            use = list(run.frames)[:: max(1, len(run.frames) // 50)][:50]
            run.sample_frames = np.asarray(
                [run.rec.frame(f, quantity="radiance") for f in use], np.float64
            )


# --------------------------------------------------------------------------- stabilisation


class _Stabiliser:
    """The registration of one run: reference, channel, corrected directions."""

    def __init__(
        self,
        reference: np.ndarray,
        channel: int,
        keep: np.ndarray,
        rotation: bool,
        static: Optional[np.ndarray] = None,
    ):
        self.channel = channel
        self.keep = keep  # (3,) 1 for the corrected (dx, dy, angle)
        self.static = static
        self.reg = _engine.FrameRegistration(
            np.ascontiguousarray(reference, np.float32),
            None if static is None else static.astype(np.uint8),
            _engine.RegistrationOptions(rotation=rotation, max_shift_px=2 * JITTER_MAX_PX),
        )
        self.shifts: Dict[int, Tuple[float, float, float]] = {}

    def measure(self, frame: np.ndarray) -> dict:
        return self.reg.register(np.ascontiguousarray(frame[self.channel], np.float32))

    def shift_of(self, frame: np.ndarray) -> np.ndarray:
        r = self.measure(frame)
        return np.array([r["dx_px"], r["dy_px"], r["angle_rad"]]) * self.keep

    def warp(self, frame: np.ndarray, shift: Optional[np.ndarray] = None) -> np.ndarray:
        s = self.shift_of(frame) if shift is None else shift
        return _engine.warp_to_reference(
            np.ascontiguousarray(frame, np.float32), float(s[0]), float(s[1]), float(s[2])
        )


def _noise(samples: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-channel noise [radiance]: the robust spread of the sampled frames'
    differences on the flattest fifth of the static scene (where neither a
    shaking camera nor the texture changes a pixel)."""
    out = np.zeros(samples.shape[1])
    d = np.diff(samples, axis=0)
    for c in range(samples.shape[1]):
        gy, gx = np.gradient(reference[c])
        g = np.hypot(gx, gy)
        flat = g <= np.percentile(g, 20)
        v = d[:, c][:, flat]
        out[c] = 1.4826 * np.median(np.abs(v - np.median(v))) / np.sqrt(2.0)
    return out


def _static_mask(samples: np.ndarray, reference: np.ndarray, noise: float) -> np.ndarray:
    """Pixels of one channel's static scene: their change over the sampled
    frames (robust spread about the median) within what noise and a camera
    motion of up to 2 px over the scene's own gradient explain; the gas,
    which changes by itself, is left out."""
    spread = 1.4826 * np.median(np.abs(samples - reference), axis=0)
    gy, gx = np.gradient(reference)
    return spread <= 3.0 * noise + 2.0 * np.hypot(gx, gy)


def _stabilisation(run: RunState, samples: np.ndarray) -> Optional[_Stabiliser]:
    """The run's stabiliser when its measured jitter matters, else None
    (``Result.info["stabilisation"]`` says which and why)."""
    info: dict = {"status": "off"}
    run.info["stabilisation"] = info
    if len(samples) < 3:
        info["status"] = "off: fewer than 3 frames to measure jitter on"
        return None
    reference = np.median(samples, axis=0)
    noise = _noise(samples, reference)
    h, w = samples.shape[-2:]
    radius = float(np.hypot(0.5 * (h - 1), 0.5 * (w - 1)))
    best = None
    for c in range(samples.shape[1]):
        static = _static_mask(samples[:, c], reference[c], float(noise[c]))
        if static.sum() < 64:
            continue
        reg = _engine.FrameRegistration(
            np.ascontiguousarray(reference[c], np.float32), static.astype(np.uint8)
        )
        p = reg.precision(float(noise[c]) if noise[c] > 0 else 1e-30)
        prec = np.array([p["dx_px"], p["dy_px"], p["angle_rad"] * radius])
        score = float(np.sort(prec)[:2].sum())
        if best is None or score < best[0]:
            best = (score, c, prec, static)
    if best is None:
        info["status"] = "off: no static part of the scene to register on"
        return None
    _, channel, prec, static = best
    info["static_fraction"] = float(static.mean())
    keep = (prec <= PRECISION_PX).astype(float)
    info["precision_px"] = [float(x) for x in prec]
    info["channel"] = int(channel)
    if not keep[:2].any():
        info["status"] = (
            "off: the scene has no texture to register on (precision "
            f"{prec[0]:.2g} px across, {prec[1]:.2g} px down)"
        )
        return None
    stab = _Stabiliser(reference[channel], channel, keep, bool(keep[2]), static)
    first = [stab.measure(f) for f in samples]
    ok = np.array([r["converged"] and r["inlier_fraction"] >= 0.5 for r in first])
    if ok.mean() < 0.5:
        # Where the only structure is the gas itself (a plate behind a steady
        # plume), the registration follows the gas and does not settle: there
        # is no static scene to measure the camera's motion on.
        info["status"] = (
            f"off: no static texture ({int((~ok).sum())} of {len(samples)} sampled frames "
            "did not register: the structure in view is the moving gas)"
        )
        return None
    shifts = np.array([[r["dx_px"], r["dy_px"], r["angle_rad"]] for r in first]) * keep
    jitter = _rms_motion(shifts[ok], radius)
    info["jitter_rms_px"] = jitter
    if jitter < JITTER_NEGLIGIBLE_PX:
        info["status"] = f"off: measured jitter {jitter:.3f} px rms is negligible"
        return None
    # A sharper reference: the median of the sampled frames put back in place.
    stable = np.asarray([stab.warp(f.astype(np.float32), s) for f, s in zip(samples, shifts)])

    # A camera's motion, put back, brings the static scene's pixels back to
    # the reference; a "motion" the gas made up does not (a plate behind a
    # puffing plume): then nothing is corrected.
    # (Each pixel's robust change over the frames beyond the noise, in
    # quadrature: gas passing now and then does not count.)
    def change(frames: np.ndarray) -> float:
        mad = np.median(np.abs(frames - np.median(frames, axis=0)), axis=0)[static]
        typical = float(np.median((1.4826 * mad) ** 2))  # over pixels too: the gas's edge aside
        return float(np.sqrt(max(0.0, typical - float(noise[channel]) ** 2)))

    before, after = change(samples[:, channel]), change(stable[:, channel])
    info["static_residual_ratio"] = float(after / before) if before > 0 else 1.0
    if not before > 0:
        info["status"] = (
            f"off: the static scene does not change beyond the noise (the measured "
            f"{jitter:.3f} px rms is the gas's, not the camera's)"
        )
        return None
    if not after < STATIC_GAIN * before:
        info["status"] = (
            f"off: the measured {jitter:.3f} px rms does not explain the static scene's "
            f"changes (put back, they are {after / before:.0%} of what they were)"
        )
        return None
    stab = _Stabiliser(np.median(stable, axis=0)[channel], channel, keep, bool(keep[2]), static)
    measured = [stab.measure(f) for f in samples]
    shifts = np.array([[r["dx_px"], r["dy_px"], r["angle_rad"]] for r in measured]) * keep
    # Not registered: no convergence, or most pixels left out (a local minimum).
    failed = sum(not r["converged"] or r["inlier_fraction"] < 0.5 for r in measured)
    stable = np.asarray([stab.warp(f.astype(np.float32), s) for f, s in zip(samples, shifts)])
    left = np.array([stab.shift_of(f) for f in stable])
    residual = _rms_motion(left, radius, about_zero=True)
    largest = float(np.max(np.hypot(shifts[:, 0], shifts[:, 1]) + np.abs(shifts[:, 2]) * radius))
    corrected = [n for n, k in zip(("dx", "dy", "rotation"), keep) if k]
    info.update(
        status="on: " + ", ".join(corrected) + " corrected",
        jitter_rms_px=_rms_motion(shifts, radius),
        residual_rms_px=residual,
        largest_px=largest,
    )
    info["not_converged"] = failed
    if not residual < 0.5 * info["jitter_rms_px"]:
        # Put back, the frames still move by most of what was measured: the
        # registration followed something other than a rigid camera motion (a
        # warm blob rising over a faint gradient read 16 px rms, 20 px left),
        # and resampling by it would move the gas instead. Nothing is corrected.
        info["status"] = (
            f"off: the measured {info['jitter_rms_px']:.3g} px rms is not a camera motion "
            f"(put back, {residual:.3g} px rms is left)"
        )
        run.warnings.add(
            "jitter-uncorrected",
            f"the frames seem to move by {info['jitter_rms_px']:.2g} px rms, but registering "
            f"them to the static scene leaves {residual:.2g} px rms: no camera motion "
            "explains it, so no frame was moved; if the camera did shake, cut the shaken "
            "part of the recording",
            largest_px=largest,
            not_converged=failed,
        )
        return None
    if largest > JITTER_MAX_PX or failed > 0.1 * len(samples):
        run.warnings.add(
            "jitter-uncorrected",
            f"the camera moved by up to {largest:.2g} px and {failed} of {len(samples)} "
            "sampled frames could not be registered to the static scene (beyond "
            f"{JITTER_MAX_PX:g} px the frames' edges are filled by repeating the border, "
            "and the background there is invented): fix the camera or cut the shaken "
            "part of the recording",
            largest_px=largest,
            not_converged=failed,
        )
    if residual > JITTER_RESIDUAL_PX:
        run.warnings.add(
            "jitter-residual",
            f"{residual:.2g} px rms of camera motion is left after stabilisation (measured "
            f"{info['jitter_rms_px']:.2g} px rms): the background and the flow see a moving "
            "scene; treat the rate with care",
            residual_rms_px=residual,
        )
    return stab


def _rms_motion(shifts: np.ndarray, radius: float, about_zero: bool = False) -> float:
    """Root-mean-square displacement [px] of rigid motions (n, 3) about their
    median (or zero): the shift plus the rotation at the image corner."""
    d = shifts if about_zero else shifts - np.median(shifts, axis=0)
    return float(np.sqrt(np.mean(d[:, 0] ** 2 + d[:, 1] ** 2 + (d[:, 2] * radius) ** 2)))


class _StabilisedFrames:
    """Frames of a recording (radiance) resampled into the reference's geometry
    as they are read (a frame source of :class:`qogi.Recording`); the motion
    measured on each frame is kept in :attr:`shifts` (frame -> (dx, dy, angle))."""

    def __init__(self, rec: Recording, stab: _Stabiliser):
        self._rec = rec
        self._stab = stab
        self.shape = rec.shape
        self.shifts: Dict[int, np.ndarray] = {}

    def shift_of_frame(self, index: int) -> np.ndarray:
        """The motion measured on frame ``index`` (dx, dy [px], angle [rad])."""
        if index not in self.shifts:
            self[index : index + 1]
        return self.shifts[index]

    def __getitem__(self, sl) -> np.ndarray:
        start = sl.start or 0
        block = self._rec.frames(start, sl.stop, quantity="radiance")
        out = np.empty_like(block)
        for k, f in enumerate(block):
            s = self._stab.shift_of(f)
            self.shifts[start + k] = s
            out[k] = self._stab.warp(f, s)
        return out


# --------------------------------------------------------------------------- filter wheel


class _Timing:
    """A filter wheel's channel offsets in frame intervals, the flow's channel
    and the static scene the channels' contrast is taken against."""

    def __init__(self, scale: np.ndarray, channel: int, reference: np.ndarray, noise: np.ndarray):
        self.scale = scale
        self.channel = channel
        self.reference = reference.astype(np.float32)
        self.noise = noise

        self.flow = FlowEstimator("dis")


def _channel_timing(run: RunState, samples: np.ndarray) -> Optional[_Timing]:
    offsets = run.rec.attrs.get("channel_time_offset_s")
    if offsets is None or run.rec.n_channels < 2:
        return None
    offsets = np.asarray(offsets, dtype=float).ravel()
    info: dict = {"offsets_s": [float(x) for x in offsets]}
    run.info["channel_timing"] = info
    if len(offsets) != run.rec.n_channels or not np.all(np.isfinite(offsets)):
        info["status"] = "off: channel_time_offset_s does not give one offset per channel"
        return None
    scale = offsets * run.scene.frame_rate
    if len(samples) < MIN_TURNS:
        # The static scene the channels' contrast is taken against is the
        # median of the sampled turns: over fewer it still holds the gas.
        info["status"] = f"off: fewer than {MIN_TURNS} turns to find the static scene in"
        return None
    if not np.any(scale):
        info["status"] = "off: the channels are simultaneous"
        return None
    reference = np.median(samples, axis=0)
    # (a floor for noise-free synthetic frames: 1e-5 of the scene's radiance)
    noise = np.maximum(_noise(samples, reference), 1e-5 * np.median(np.abs(reference), axis=(1, 2)))
    contrast = np.abs(samples - reference) / noise[None, :, None, None]
    channel = int(np.argmax(np.percentile(contrast, 99.5, axis=(0, 2, 3))))
    info["status"] = f"on: channels moved along the gas's flow (channel {channel}) to the turn time"
    info["flow_channel"] = channel
    return _Timing(scale, channel, reference, noise)


class _CommonTimeFrames:
    """Frames whose channels are brought to the turn's time as they are read:
    channel k's contrast against the static scene moved back along the gas's
    displacement over its offset (a frame source of :class:`qogi.Recording`)."""

    def __init__(self, rec: Recording, timing: _Timing):
        self._rec = rec
        self._t = timing
        self.shape = rec.shape

    def __getitem__(self, sl) -> np.ndarray:
        n = self._rec.n_frames
        start, stop = sl.start or 0, n if sl.stop is None else sl.stop
        lo, hi = max(0, start - 1), min(n, stop + 1)
        block = self._rec.frames(lo, hi, quantity="radiance")
        out: List[np.ndarray] = []
        for i in range(start, stop):
            a, b = max(lo, i - 1), min(hi - 1, i + 1)
            out.append(self._common_time(block[i - lo], block[a - lo], block[b - lo], b - a))
        return np.asarray(out, np.float32).reshape((stop - start,) + block.shape[1:])

    def _gas(self, frame: np.ndarray) -> np.ndarray:
        c = self._t.channel
        return np.ascontiguousarray(
            (frame[c] - self._t.reference[c]) / np.float32(self._t.noise[c]), np.float32
        )

    def _common_time(self, frame, prev, nxt, span: int) -> np.ndarray:
        if span == 0:
            return frame
        f = self._t.flow.calc(self._gas(prev), self._gas(nxt))
        # Displacement per frame interval where there is gas (3 sigma); none elsewhere.
        gas = np.abs(self._gas(frame)) > 3.0
        u = np.where(gas, f.u / span, 0.0).astype(np.float32)
        v = np.where(gas, f.v / span, 0.0).astype(np.float32)
        contrast = np.ascontiguousarray(frame - self._t.reference, np.float32)
        out = np.empty_like(frame)
        for k, s in enumerate(self._t.scale):
            out[k] = self._t.reference[k] + _engine.warp_along_flow(contrast[k], u, v, float(s))
        return out


def _view(rec: Recording, source) -> Recording:
    """``rec`` with its frames read through ``source`` (radiance)."""
    out = Recording(
        source=source,
        time_s=rec.time_s,
        quantity="radiance",
        camera=rec.camera,
        scene=rec.scene,
        truth=rec.truth,
        path=rec.path,
        nonfinite=rec.nonfinite,
        attrs=rec.attrs,
    )
    out.n_invalid = rec.n_invalid
    for name in ("channel_time_s", "scene_origin", "warnings"):
        if hasattr(rec, name):
            setattr(out, name, getattr(rec, name))
    return out
