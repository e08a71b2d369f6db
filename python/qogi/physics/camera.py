"""The camera: its description (:class:`Camera`: geometry, timing, channel
responses), calibration, NETD noise and warm-optics emission.

:class:`Camera` is what a recording says of its camera (docs/recording.md,
checked against the recording contract's ranges, :mod:`qogi.contract`). The
other three are independent parts, each a thin layer over the C++ engine
(``cpp/engine/camera``); see ``docs/camera.md`` for the models.

Calibration (thesis section 2.5)
    :func:`fit_calibration` fits, per channel, a per-pixel two-point
    non-uniformity correction and the counts-flux curve
    ``counts / t_int = G L + O (+ Q L^2)`` from frames of uniform blackbody
    scenes; :class:`Calibration` applies it to raw frame stacks
    (counts -> band radiance -> radiometric temperature, and back) and saves
    to / loads from ``.npz`` or an HDF5 group.
Noise
    :func:`add_netd_noise` adds seeded Gaussian noise of standard deviation
    ``sigma_L = NETD x dL/dT(T_bg)`` per channel.
Warm optics (thesis Fig. 39, section 4.3.3)
    :class:`ChannelOptics` holds a channel's detector, filter and lens curves
    and gives the radiance the warm filter and lens add
    (:meth:`ChannelOptics.warm_radiance`); :func:`add_warm_optics` and
    :func:`correct_warm_optics` apply it to band radiances or frame stacks.

Units: counts [counts], integration time [s], band radiance [W/(m2 sr)],
temperature [K], wavenumber [cm-1].
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any, List, Optional, Sequence, Union

import numpy as np

from .. import _engine
from ..contract import MEMORY, RecordingError, check_range
from ..errors import UsageError
from ..files import atomic_path
from ..hdf5_files import h5_writing
from .optics import SpectralResponse, channel_problem
from .radiometry import radiance_to_temperature, temperature_to_radiance

__all__ = [
    # the camera
    "Camera",
    # calibration
    "CalibrationScene",
    "Calibration",
    "fit_calibration",
    # noise
    "netd_radiance_sigma",
    "add_netd_noise",
    # warm optics
    "ChannelOptics",
    "camera_optics",
    "warm_optics_radiance",
    "add_warm_optics",
    "correct_warm_optics",
]


# --------------------------------------------------------------------------- the camera


def check_channels(channels, path: str, num_frame_channels: Optional[int] = None) -> None:
    """:func:`qogi.physics.optics.channel_problem` as a RecordingError at /camera/channels."""
    bad = channel_problem(channels, num_frame_channels)
    if bad is not None:
        raise RecordingError(path, "/camera/channels" + bad[0], bad[1], bad[2])


@dataclass
class Camera:
    """The camera: name, geometry, timing and one spectral response per channel.

    Attributes
    ----------
    name : str
        Camera model or identifier.
    ifov_rad : float, rad
        Instantaneous field of view of one pixel (its angular size), in
        (0, 0.1].
    channels : list of SpectralResponse
        One response (filter x lens x detector) per frame channel, in order.
    frame_rate_hz : float or None, Hz
        Nominal frame rate. ``None`` only while building a recording: it is
        then taken from the typical frame interval (see typical_interval) of ``time_s``.
    netd_K : float or None, K
        Noise-equivalent temperature difference, optional, in (0, 10].
    width, height : int or None, pixels
        Sensor resolution, when known (presets know it; a recording's frames
        carry their own shape). Not stored in recording files.
    description : str
        Where the model's numbers come from (presets); not stored in files.
    """

    name: str
    ifov_rad: float
    channels: List[SpectralResponse]
    frame_rate_hz: Optional[float] = None
    netd_K: Optional[float] = None
    width: Optional[int] = None
    height: Optional[int] = None
    description: str = ""

    def validate(self, path: str = MEMORY) -> None:
        """Raise :class:`RecordingError` unless every field is in range."""
        if not isinstance(self.name, str):
            raise RecordingError(path, "/camera attr name", f"must be a string; got {self.name!r}")
        check_range(
            "camera.ifov_rad",
            self.ifov_rad,
            path,
            "/camera attr ifov_rad",
            "give the angular size of one pixel in radians "
            "(horizontal field of view / pixels across)",
        )
        if self.frame_rate_hz is not None:
            check_range(
                "camera.frame_rate_hz", self.frame_rate_hz, path, "/camera attr frame_rate_hz"
            )
        if self.netd_K is not None:
            check_range("camera.netd_K", self.netd_K, path, "/camera attr netd_K")
        check_channels(self.channels, path)


def _channel_list(channels) -> list:
    """A camera (anything with ``.channels``), one SpectralResponse or a list."""
    if hasattr(channels, "channels"):
        channels = channels.channels
    if isinstance(channels, _engine.SpectralResponse):
        channels = [channels]
    out = list(channels)
    bad = channel_problem(out)
    if bad is not None:
        raise UsageError(f"channels{bad[0]}: {bad[1]}. Fix: {bad[2]}")
    return out


def _as_response(r) -> SpectralResponse:
    """An engine SpectralResponse as the public class (which has the methods)."""
    if isinstance(r, SpectralResponse):
        return r
    return SpectralResponse(r.nu_cm1, r.response, r.name)


# =============================================================================
# Calibration
# =============================================================================


@dataclass
class CalibrationScene:
    """Raw frames of a uniform blackbody filling the field of view.

    Parameters
    ----------
    blackbody_temperature_K : float, K
        The source temperature.
    frames : array, counts
        Raw counts, shaped (N, C, H, W) for N frames of C channels; for a
        single-channel camera (N, H, W) or (H, W) are accepted too. Any
        numeric dtype (uint16 raw frames are converted to float32).
    integration_time_s : float or sequence of float, s
        Integration (exposure) time, one value for all channels or one per
        channel.
    """

    blackbody_temperature_K: float
    frames: Any
    integration_time_s: Union[float, Sequence[float]]


def _frames_nchw(frames, num_channels: int, what: str) -> np.ndarray:
    """float32, C-contiguous, (N, C, H, W)."""
    a = np.asarray(frames)
    if a.ndim == 4:
        pass
    elif num_channels == 1 and a.ndim in (2, 3):
        a = a.reshape((-1, 1) + a.shape[-2:])
    else:
        raise ValueError(
            f"{what} must be shaped (N, C, H, W) with C = {num_channels} channels"
            f"{' (or (N, H, W))' if num_channels == 1 else ''}; got shape {a.shape}"
        )
    if a.shape[1] != num_channels:
        raise ValueError(
            f"{what} has {a.shape[1]} channels on axis 1 but the calibration has "
            f"{num_channels}; shape {a.shape}"
        )
    if not np.issubdtype(a.dtype, np.number) or np.issubdtype(a.dtype, np.complexfloating):
        raise TypeError(f"{what} must be real numbers; got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.float32)


def _per_channel_times(t, num_channels: int, what: str) -> np.ndarray:
    a = np.asarray(t, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(num_channels, float(a))
    if a.shape != (num_channels,):
        raise ValueError(
            f"{what} must be one value or one per channel ({num_channels}); got shape {a.shape}"
        )
    if not np.all(np.isfinite(a) & (a > 0)):
        raise ValueError(f"{what} must be finite and > 0 s; got {a.tolist()}")
    return a


def fit_calibration(
    scenes: Sequence[CalibrationScene],
    channels,
    *,
    quadratic: bool = False,
    saturation_counts: float = 65535.0,
    min_valid_counts: float = 0.0,
    bad_response_tolerance: float = 0.3,
    bad_noise_factor: float = 6.0,
    max_bad_fraction: float = 0.05,
    nuc_cold_scene: int = -1,
    nuc_hot_scene: int = -1,
    blackbody_emissivity: float = 1.0,
    ambient_temperature_K: float = 0.0,
    num_threads: int = 0,
    progress=None,
) -> Calibration:
    """Fit a radiometric calibration from uniform blackbody scenes.

    Model (per pixel p, integration time t, scene band radiance L)::

        counts_p = t (g_p L + o_p)          [+ small nonlinearity]

    so ``f_p = counts_p / t`` [counts/s] does not depend on t. Per channel:

    1. two-point non-uniformity correction ``f'_p = a_p f_p + b_p`` mapping
       every pixel onto the mean good pixel, from the temporal mean fluxes of
       two scenes (default the coldest and the hottest);
    2. bad pixels: out of range in any frame, NUC responsivity off the median
       by more than ``bad_response_tolerance``, or temporal noise above
       ``bad_noise_factor`` x the median;
    3. the counts-flux curve ``F = G L + O`` (``+ Q L^2`` if ``quadratic``)
       fitted by least squares to the corrected mean flux of every scene
       against its source radiance
       ``L_k = eps L(T_k) + (1 - eps) L(T_amb)`` (``L`` through the
       channel's response, thesis eq. 14); residuals per scene in counts/s
       and kelvin (:meth:`Calibration.report`).

    Parameters
    ----------
    scenes : sequence of CalibrationScene
        At least 3 distinct temperatures (4 with ``quadratic``); frames of one
        size. Scenes may use different integration times.
    channels : camera, SpectralResponse or list of them
        One response per channel, in the frames' channel order.
    quadratic : bool, default False
        Fit the quadratic term Q.
    saturation_counts : float, counts, default 65535
        Raw counts at or above this are saturated.
    min_valid_counts : float, counts, default 0
        Raw counts at or below this are under range.
    bad_response_tolerance : float, default 0.3
        Relative responsivity departure from the median that makes a bad pixel.
    bad_noise_factor : float, default 6
        Temporal-noise multiple of the median that makes a bad pixel (needs
        >= 2 frames in each NUC scene).
    max_bad_fraction : float, default 0.05
        More bad (or, in one scene, saturated) pixels than this is an error.
    nuc_cold_scene, nuc_hot_scene : int, default -1
        Indices of the NUC scenes; -1 picks the coldest / hottest.
    blackbody_emissivity : float, default 1
        Emissivity of the source, in (0, 1].
    ambient_temperature_K : float, K, default 0
        Temperature of the surroundings the source reflects (needed when
        ``blackbody_emissivity < 1``).
    num_threads : int, default 0 (all cores)
    progress : callable(fraction) -> bool or None, optional
        Called during the per-pixel statistics; return False to cancel.

    Returns
    -------
    Calibration

    Raises
    ------
    ValueError
        Naming the channel and the problem: too few temperatures, saturated
        or non-monotonic data, too many bad pixels, shapes that disagree,
        non-positive integration times, non-finite counts.
    """
    chans = _channel_list(channels)
    nc = len(chans)
    scenes = list(scenes)
    if not scenes:
        raise ValueError("fit_calibration needs calibration scenes; got none")
    opts = _engine.CalibrationOptions(
        quadratic=quadratic,
        saturation_counts=saturation_counts,
        min_valid_counts=min_valid_counts,
        bad_response_tolerance=bad_response_tolerance,
        bad_noise_factor=bad_noise_factor,
        max_bad_fraction=max_bad_fraction,
        nuc_cold_scene=nuc_cold_scene,
        nuc_hot_scene=nuc_hot_scene,
        blackbody_emissivity=blackbody_emissivity,
        ambient_temperature_K=ambient_temperature_K,
        num_threads=num_threads,
    )
    prepared = []
    for k, s in enumerate(scenes):
        if not isinstance(s, CalibrationScene):
            raise TypeError(
                f"scenes[{k}] must be a qogi.camera.CalibrationScene; got {type(s).__name__}"
            )
        frames = _frames_nchw(s.frames, nc, f"scenes[{k}].frames")
        times = _per_channel_times(s.integration_time_s, nc, f"scenes[{k}].integration_time_s")
        prepared.append((float(s.blackbody_temperature_K), times, frames))
    shapes = {p[2].shape[-2:] for p in prepared}
    if len(shapes) > 1:
        raise ValueError(
            "calibration scenes must share one frame size (H, W); got "
            + ", ".join(str(p[2].shape[-2:]) for p in prepared)
        )
    fitted = []
    for c, ch in enumerate(chans):
        engine_scenes = [
            (t, float(times[c]), np.ascontiguousarray(frames[:, c]))
            for t, times, frames in prepared
        ]
        try:
            fitted.append(_engine._fit_channel_calibration(ch, engine_scenes, opts, progress))
        except ValueError as e:
            raise ValueError(f"channel {c} ({ch.name!r}): {e}") from None
    return Calibration(fitted)


_POINT_COLUMNS = (
    "blackbody_temperature_K",
    "integration_time_s",
    "radiance",
    "mean_flux",
    "residual_flux",
    "residual_K",
    "spatial_noise_K",
)
_FORMAT = "qogi-calibration"
_VERSION = 1


class Calibration:
    """A camera's radiometric calibration, one :class:`ChannelCalibration
    <qogi._engine.ChannelCalibration>` per channel.

    Built by :func:`fit_calibration` or :meth:`load`. Frame stacks are laid
    out (..., C, H, W), channel on axis -3 (the recording contract's
    (T, C, H, W)); a single-channel calibration also takes (..., H, W).

    Attributes
    ----------
    channels : list of qogi._engine.ChannelCalibration
        Per channel: ``nuc_gain`` [-] and ``nuc_offset`` [counts/s] maps,
        ``bad_pixels`` (bool map), ``curve`` (G [counts/s per W/(m2 sr)],
        O [counts/s], Q), ``points`` (fit diagnostics), ``rms_residual_K``.
    last_stats : dict
        Counts from the last conversion: ``out_of_range`` (saturated or
        under-range values, set to NaN), ``replaced`` (bad-pixel values
        replaced by their good neighbours' mean), ``unreplaced`` (NaN).
    """

    def __init__(self, channels: Sequence[Any]):
        chans = _typed_list(
            channels,
            _engine.ChannelCalibration,
            "channels",
            "a ChannelCalibration",
            "a Calibration needs at least one channel",
        )
        shapes = {(c.height, c.width) for c in chans}
        if len(shapes) > 1:
            raise ValueError(f"channel calibrations must share one frame size; got {shapes}")
        self.channels = chans
        self.last_stats = {"out_of_range": 0, "replaced": 0, "unreplaced": 0}

    # -- description ----------------------------------------------------------
    @property
    def num_channels(self) -> int:
        return len(self.channels)

    @property
    def frame_shape(self) -> tuple:
        """(H, W) of the calibrated frames."""
        return (self.channels[0].height, self.channels[0].width)

    @property
    def responses(self) -> list:
        """The channels' spectral responses (list of SpectralResponse)."""
        return [_as_response(c.channel) for c in self.channels]

    def __repr__(self) -> str:
        h, w = self.frame_shape
        names = ", ".join(repr(c.channel.name) for c in self.channels)
        return f"Calibration({self.num_channels} channels [{names}], {h}x{w} pixels)"

    def report(self) -> str:
        """A plain-text table of the fit: curve, bad pixels and per-scene residuals."""
        lines = []
        for k, c in enumerate(self.channels):
            cv = c.curve
            lines.append(
                f"channel {k} {c.channel.name!r}: G = {cv.gain:.6g} counts/s per "
                f"W/(m2 sr), O = {cv.offset:.6g} counts/s, Q = {cv.quadratic:.6g}; "
                f"{c.num_bad_pixels} bad pixels; rms residual "
                f"{c.rms_residual_K * 1e3:.3f} mK"
            )
            lines.append(
                "    T [K]    t_int [s]   L [W/(m2 sr)]   F [counts/s]   "
                "residual [counts/s]   residual [mK]   spatial noise [mK]"
            )
            p = c.points
            for i in range(len(p["radiance"])):
                lines.append(
                    f"  {p['blackbody_temperature_K'][i]:7.2f}  "
                    f"{p['integration_time_s'][i]:10.4g}  {p['radiance'][i]:14.6g}  "
                    f"{p['mean_flux'][i]:13.6g}  {p['residual_flux'][i]:20.4g}  "
                    f"{p['residual_K'][i] * 1e3:14.3f}  "
                    f"{p['spatial_noise_K'][i] * 1e3:18.3f}"
                )
        return "\n".join(lines)

    # -- conversions ----------------------------------------------------------
    def _layout(self, frames, what: str):
        a = np.asarray(frames)
        nc = self.num_channels
        h, w = self.frame_shape
        if a.ndim >= 2 and a.shape[-2:] != (h, w):
            raise ValueError(
                f"{what} frames are {a.shape[-2:]} pixels but the calibration is "
                f"for {(h, w)}; shape {a.shape}"
            )
        if nc == 1 and (a.ndim == 2 or (a.ndim >= 3 and a.shape[-3] != 1)):
            lead = a.shape[:-2]
            shape = lead + (1, h, w)
        else:
            if a.ndim < 3 or a.shape[-3] != nc:
                raise ValueError(
                    f"{what} must be shaped (..., C, H, W) with C = {nc} channels; "
                    f"got shape {a.shape}"
                )
            lead = a.shape[:-3]
            shape = a.shape
        n = int(np.prod(lead, dtype=np.int64)) if lead else 1
        return a, shape, lead, n

    def _times(self, integration_time_s, lead, n) -> np.ndarray:
        nc = self.num_channels
        t = np.asarray(integration_time_s, dtype=np.float64)
        if nc == 1 and lead and t.shape == tuple(lead):
            t = t[..., None]  # one time per frame of a single-channel stack
        tb: Optional[np.ndarray]
        try:
            tb = np.broadcast_to(t, tuple(lead) + (nc,)) if t.ndim <= len(lead) + 1 else None
        except ValueError:
            tb = None
        if tb is None:
            raise ValueError(
                "integration_time_s must broadcast to (..., C) = "
                f"{tuple(lead) + (nc,)}: one value, one per channel or one per "
                f"frame and channel; got shape "
                f"{np.shape(integration_time_s)}"
            )
        t = np.ascontiguousarray(tb).reshape(n, nc)
        if not np.all(np.isfinite(t) & (t > 0)):
            raise ValueError("integration_time_s must be finite and > 0 s")
        return t

    def counts_to_radiance(
        self,
        raw,
        integration_time_s,
        *,
        replace_bad_pixels: bool = True,
        num_threads: int = 0,
        progress=None,
    ) -> np.ndarray:
        """Raw counts -> band radiance [W/(m2 sr)], float32.

        ``L = F^-1(a_p raw / t + b_p)`` per pixel. Saturated or under-range
        values become NaN (counted in :attr:`last_stats`); bad pixels take the
        mean of their good 3x3 neighbours (``replace_bad_pixels``) or NaN.

        Parameters
        ----------
        raw : array, counts, (..., C, H, W)
        integration_time_s : float or array, s
            Broadcast to (..., C): one value, one per channel, or one per
            frame and channel.
        replace_bad_pixels : bool, default True
        num_threads : int, default 0 (all cores)
        progress : callable(fraction) -> bool or None, optional
            Receives the overall finished fraction; return False to cancel.
        """
        a, shape, lead, n = self._layout(raw, "raw")
        times = self._times(integration_time_s, lead, n)
        src = np.ascontiguousarray(a, dtype=np.float32).reshape((n,) + shape[-3:])
        out = np.empty_like(src)
        stats = {"out_of_range": 0, "replaced": 0, "unreplaced": 0}
        nc = self.num_channels
        for c, cal in enumerate(self.channels):
            step = (
                None if progress is None else (lambda f, c=c: progress((c + f) / nc))
            )  # overall fraction
            s = cal._counts_to_radiance(
                src,
                c,
                np.ascontiguousarray(times[:, c]),
                out,
                replace_bad_pixels,
                num_threads,
                step,
            )
            for key in stats:
                stats[key] += s[key]
        self.last_stats = stats
        return out.reshape(a.shape)

    def radiance_to_counts(
        self, radiance, integration_time_s, *, num_threads: int = 0
    ) -> np.ndarray:
        """Band radiance [W/(m2 sr)] -> the raw counts each pixel reads
        (the exact inverse of :meth:`counts_to_radiance` at good pixels; NaN
        at bad pixels; not clipped to the camera's range). float32."""
        a, shape, lead, n = self._layout(radiance, "radiance")
        times = self._times(integration_time_s, lead, n)
        src = np.ascontiguousarray(a, dtype=np.float32).reshape((n,) + shape[-3:])
        out = np.empty_like(src)
        for c, cal in enumerate(self.channels):
            cal._radiance_to_counts(src, c, np.ascontiguousarray(times[:, c]), out, num_threads)
        return out.reshape(a.shape)

    def radiance_to_temperature(self, radiance) -> np.ndarray:
        """Band radiance [W/(m2 sr)] -> radiometric temperature [K] through
        each channel's response (:mod:`qogi.radiometry` tables; NaN stays NaN)."""

        a, shape, _, _ = self._layout(radiance, "radiance")
        return radiance_to_temperature(
            np.asarray(a).reshape(shape), self.responses, axis=-3
        ).reshape(a.shape)

    def temperature_to_radiance(self, temperature_K) -> np.ndarray:
        """Radiometric temperature [K] -> band radiance [W/(m2 sr)]."""

        a, shape, _, _ = self._layout(temperature_K, "temperature")
        return temperature_to_radiance(
            np.asarray(a).reshape(shape), self.responses, axis=-3
        ).reshape(a.shape)

    def counts_to_temperature(self, raw, integration_time_s, **kwargs) -> np.ndarray:
        """Raw counts -> radiometric temperature [K] (float32)."""
        return self.radiance_to_temperature(
            self.counts_to_radiance(raw, integration_time_s, **kwargs)
        )

    def apply(self, raw, integration_time_s, quantity: str = "radiance", **kwargs) -> np.ndarray:
        """Calibrate raw frames into ``quantity``: ``"radiance"`` (band
        radiance, W/(m2 sr)) or ``"radiometric_temperature"`` (K), the two
        quantities of the recording contract. Keyword arguments go to
        :meth:`counts_to_radiance`."""
        if quantity == "radiance":
            return self.counts_to_radiance(raw, integration_time_s, **kwargs)
        if quantity == "radiometric_temperature":
            return self.counts_to_temperature(raw, integration_time_s, **kwargs)
        raise ValueError(
            f"quantity must be 'radiance' or 'radiometric_temperature'; got {quantity!r}"
        )

    # -- persistence ----------------------------------------------------------
    def _arrays(self) -> dict:
        out = {
            "format": np.array(_FORMAT),
            "version": np.array(_VERSION),
            "num_channels": np.array(self.num_channels),
        }
        for k, c in enumerate(self.channels):
            p = f"channels/{k}/"
            out[p + "name"] = np.array(c.channel.name)
            out[p + "wavenumber_cm1"] = np.asarray(c.channel.nu_cm1)
            out[p + "response"] = np.asarray(c.channel.response)
            out[p + "nuc_gain"] = c.nuc_gain
            out[p + "nuc_offset"] = c.nuc_offset
            out[p + "bad_pixels"] = c.bad_pixels.astype(np.uint8)
            out[p + "curve"] = np.array([c.curve.gain, c.curve.offset, c.curve.quadratic])
            out[p + "range_counts"] = np.array([c.min_valid_counts, c.saturation_counts])
            for col, v in c.points.items():
                out[p + "points/" + col] = v
        return out

    @staticmethod
    def _from_arrays(get, where: str) -> Calibration:
        fmt = str(get("format"))
        if fmt != _FORMAT:
            raise ValueError(f"{where} is not a qogi calibration (format {fmt!r})")
        version = int(get("version"))
        if version > _VERSION:
            raise ValueError(
                f"{where} has calibration format version {version}; this qogi "
                f"reads up to {_VERSION}: upgrade qogi"
            )
        chans = []
        for k in range(int(get("num_channels"))):
            p = f"channels/{k}/"
            resp = SpectralResponse(
                get(p + "wavenumber_cm1"), get(p + "response"), str(get(p + "name"))
            )
            g, o, q = (float(v) for v in get(p + "curve"))
            lo, hi = (float(v) for v in get(p + "range_counts"))
            points = {
                col: np.asarray(get(p + "points/" + col), dtype=np.float64)
                for col in _POINT_COLUMNS
            }
            chans.append(
                _engine.ChannelCalibration(
                    resp,
                    np.asarray(get(p + "nuc_gain"), dtype=np.float64),
                    np.asarray(get(p + "nuc_offset"), dtype=np.float64),
                    np.asarray(get(p + "bad_pixels"), dtype=np.uint8),
                    _engine.CountsFluxCurve(g, o, q),
                    points,
                    hi,
                    lo,
                )
            )
        return Calibration(chans)

    def save(self, target, group: str = "calibration") -> None:
        """Save to a ``.npz`` file, an HDF5 file (``.h5``/``.hdf5``: into
        ``group``, replacing it) or an open ``h5py.Group`` (into ``group``
        below it)."""
        arrays = self._arrays()

        if isinstance(target, (str, os.PathLike)) and str(target).endswith(".npz"):
            with atomic_path(target) as tmp:
                np.savez(tmp, **arrays)
            return
        import h5py

        if isinstance(target, (str, os.PathLike)):
            # Into a copy of the file, renamed over it when complete.
            with atomic_path(target) as tmp:
                if os.path.exists(target):
                    import shutil

                    shutil.copyfile(target, tmp)
                with h5_writing(tmp, "a") as f:  # a full disk: dropped, not left open
                    self._save_h5(f, group, arrays)
        elif isinstance(target, h5py.Group):
            self._save_h5(target, group, arrays)
        else:
            raise TypeError(
                "target must be a .npz path, an HDF5 path or an h5py.Group; "
                f"got {type(target).__name__}"
            )

    @staticmethod
    def _save_h5(parent, group: str, arrays: dict) -> None:
        if group in parent:
            del parent[group]
        g = parent.create_group(group)
        for key, v in arrays.items():
            if v.dtype.kind == "U":
                g.create_dataset(key, data=str(v))
            else:
                g.create_dataset(key, data=v)

    @classmethod
    def load(cls, source, group: str = "calibration") -> Calibration:
        """Load what :meth:`save` wrote (``.npz`` path, HDF5 path or
        ``h5py.Group``)."""
        if isinstance(source, (str, os.PathLike)) and str(source).endswith(".npz"):
            with np.load(source, allow_pickle=False) as z:

                def get(key):
                    if key not in z:
                        raise ValueError(f"{source}: calibration entry {key!r} is missing")
                    return z[key][()]

                return cls._from_arrays(get, str(source))
        import h5py

        if isinstance(source, (str, os.PathLike)):
            with h5py.File(source, "r") as f:
                return cls._load_h5(f, group, f"{source}:/{group}")
        if isinstance(source, h5py.Group):
            return cls._load_h5(source, group, f"{source.name}/{group}")
        raise TypeError(
            "source must be a .npz path, an HDF5 path or an h5py.Group; "
            f"got {type(source).__name__}"
        )

    @classmethod
    def _load_h5(cls, parent, group: str, where: str) -> Calibration:
        if group not in parent:
            raise ValueError(f"{where}: no calibration group {group!r}")
        g = parent[group]

        def get(key):
            if key not in g:
                raise ValueError(f"{where}: calibration entry {key!r} is missing")
            v = g[key][()]
            return v.decode() if isinstance(v, bytes) else v

        return cls._from_arrays(get, where)


# =============================================================================
# Noise
# =============================================================================


def _per_channel(value, n: int, what: str) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{what} must be one value or one per channel ({n}); got shape {a.shape}")
    return a


def netd_radiance_sigma(channels, netd_K=None, background_temperature_K=288.15) -> np.ndarray:
    """Noise standard deviation in radiance units, per channel.

    ``sigma_L,c = NETD_c x dL_c/dT (T_bg,c)`` [W/(m2 sr)], with
    ``L_c(T) = integral r_c B(nu, T) dnu`` (thesis eq. 14).

    Parameters
    ----------
    channels : camera, SpectralResponse or list of them
    netd_K : float or sequence, K, optional
        NETD, one value or one per channel; default: the camera's ``netd_K``.
    background_temperature_K : float or sequence, K, default 288.15
        The scene's (radiometric) background temperature, one or per channel.
    """
    chans = _channel_list(channels)
    if netd_K is None:
        if not hasattr(channels, "netd_K"):
            raise ValueError("netd_K is needed (the channels are not a camera with a netd_K)")
        netd_K = channels.netd_K
    netd = _per_channel(netd_K, len(chans), "netd_K")
    t_bg = _per_channel(background_temperature_K, len(chans), "background_temperature_K")
    return np.array(
        [_engine.netd_radiance_sigma(ch, float(n), float(t)) for ch, n, t in zip(chans, netd, t_bg)]
    )


def add_netd_noise(
    frames,
    channels,
    netd_K=None,
    background_temperature_K=288.15,
    *,
    seed: int,
    offset: int = 0,
    in_place: bool = False,
    num_threads: int = 0,
    progress=None,
) -> np.ndarray:
    """Add NETD-based Gaussian noise to band-radiance frames.

    Each value of channel c gets an independent draw from
    ``N(0, sigma_L,c^2)``, ``sigma_L,c = NETD_c x dL_c/dT(T_bg,c)``
    (:func:`netd_radiance_sigma`). Reproducible: the draw for element i (in
    C order of the array) depends only on ``(seed, offset + i)``, not on the
    thread count; noising a long stack in pieces with ``offset`` = elements
    already done gives the same noise as one call.

    Parameters
    ----------
    frames : array, W/(m2 sr), (..., C, H, W)
        Band radiance frames; a single channel may be (..., H, W).
    channels, netd_K, background_temperature_K
        As in :func:`netd_radiance_sigma`.
    seed : int
        Seed (0 <= seed < 2**64).
    in_place : bool, default False
        Add into ``frames`` (must then be C-contiguous float32).

    Returns
    -------
    ndarray, float32
    """
    chans = _channel_list(channels)
    sigma = netd_radiance_sigma(channels, netd_K, background_temperature_K)
    a = np.asarray(frames)
    nc = len(chans)
    if a.ndim < 2 or (nc > 1 and (a.ndim < 3 or a.shape[-3] != nc)):
        raise ValueError(
            f"frames must be shaped (..., C, H, W) with C = {nc} channels; got shape {a.shape}"
        )
    if in_place:
        if not (
            isinstance(frames, np.ndarray)
            and frames.dtype == np.float32
            and frames.flags.c_contiguous
            and frames.flags.writeable
        ):
            raise ValueError("in_place=True needs a writeable C-contiguous float32 array")
        out = frames
    else:
        out = np.array(a, dtype=np.float32, order="C", copy=True)
    if not (0 <= int(seed) < 2**64 and 0 <= int(offset) < 2**64):
        raise ValueError(f"seed and offset must be within [0, 2**64); got {seed} and {offset}")
    pixels = a.shape[-1] * a.shape[-2]
    _engine._add_gaussian_noise(
        out.reshape(-1), pixels, sigma, int(seed), int(offset), num_threads, progress
    )
    return out


# =============================================================================
# Warm optics
# =============================================================================


class ChannelOptics(_engine.ChannelOptics):
    """A channel's optics: detector, filter and lens, and their emission.

    The lens (transmittance ``tau_l``, non-reflecting: emissivity
    ``1 - tau_l``) sits in front of the filter (transmittance ``tau_f``,
    reflectance ``rho_f``, emissivity ``1 - tau_f - rho_f``), seen by a
    detector of relative response ``d``. The detector measures (thesis
    section 4.3.3, Fig. 39)::

        L_meas = integral d [tau_f tau_l L_scene + tau_f (1 - tau_l) B(T_lens)
                             + (1 - tau_f - rho_f) B(T_filter)
                             + rho_f B(T_refl)] dnu
               = L_channel + W(T_lens, T_filter, T_refl)

    where ``L_channel`` is the band radiance through the channel response
    ``r = d tau_f tau_l`` (:attr:`response`, what the forward models
    compute) and ``W`` (:meth:`warm_radiance`) does not depend on the scene.
    ``T_refl`` is what the filter reflects from the detector side (default
    0 K: the cold shield, no emission). A temperature of 0 K means "cold".

    Parameters
    ----------
    nu_cm1 : array, cm-1
        Strictly increasing wavenumbers (>= 2 samples); all curves are linear
        between samples and zero outside.
    detector_response : array, >= 0
    filter_transmittance : array, in [0, 1]
    lens_transmittance : array, in [0, 1]
    filter_reflectance : array in [0, 1], optional
        Default 0 (an absorbing filter). Interference filters block mostly by
        reflection; give their reflectance, or their out-of-band emissivity
        is overstated.
    name : str
    """

    def __repr__(self) -> str:
        nu = self.nu_cm1
        return (
            f"ChannelOptics(name={self.name!r}, {len(nu)} samples, {nu[0]:.1f}-{nu[-1]:.1f} cm-1)"
        )

    @classmethod
    def _from_engine(cls, o) -> ChannelOptics:
        return cls(
            o.nu_cm1,
            o.detector_response,
            o.filter_transmittance,
            o.lens_transmittance,
            o.filter_reflectance,
            o.name,
        )

    @property
    def response(self) -> SpectralResponse:
        """The channel response ``r = d tau_f tau_l`` (a SpectralResponse)."""
        return _as_response(self._response)

    def warm_radiance(self, lens_temperature_K, filter_temperature_K, reflected_temperature_K=0.0):
        """The warm-optics radiance W [W/(m2 sr)].

        ``W = integral d [tau_f (1 - tau_l) B(T_lens)
        + (1 - tau_f - rho_f) B(T_filter) + rho_f B(T_refl)] dnu``.
        Temperatures [K] (>= 0; 0 = cold) broadcast against each other;
        returns a float or an array of their broadcast shape.
        """
        tl, tf, tr = np.broadcast_arrays(
            *[
                np.asarray(x, dtype=np.float64)
                for x in (lens_temperature_K, filter_temperature_K, reflected_temperature_K)
            ]
        )
        out = self._warm_radiance(
            np.ascontiguousarray(tl).ravel(),
            np.ascontiguousarray(tf).ravel(),
            np.ascontiguousarray(tr).ravel(),
        ).reshape(tl.shape)
        return float(out) if out.ndim == 0 else out

    def measured(
        self,
        channel_radiance,
        lens_temperature_K,
        filter_temperature_K,
        reflected_temperature_K=0.0,
    ):
        """Forward: ``L_channel + W`` [W/(m2 sr)] (broadcast)."""
        return np.asarray(channel_radiance) + self.warm_radiance(
            lens_temperature_K, filter_temperature_K, reflected_temperature_K
        )

    def corrected(
        self,
        measured_radiance,
        lens_temperature_K,
        filter_temperature_K,
        reflected_temperature_K=0.0,
    ):
        """Correction: ``L_meas - W`` [W/(m2 sr)], the exact inverse of
        :meth:`measured`."""
        return np.asarray(measured_radiance) - self.warm_radiance(
            lens_temperature_K, filter_temperature_K, reflected_temperature_K
        )


def camera_optics(name: str) -> list:
    """The filter, lens and detector curves of a shipped preset's channels
    (list of :class:`ChannelOptics`, in the preset's channel order), built
    from the same curves as the preset so that each ``.response`` reproduces
    the preset's channel response. For ``gf320`` the filter is cold (inside
    the dewar): pass its cryogenic temperature, or 0, as the filter
    temperature."""
    return [ChannelOptics._from_engine(o) for o in _engine.camera_preset_optics(name)]


def _optics_list(optics) -> list:
    if isinstance(optics, _engine.ChannelOptics):
        optics = [optics]
    return _typed_list(
        optics,
        _engine.ChannelOptics,
        "optics",
        "a qogi.camera.ChannelOptics",
        "at least one ChannelOptics is needed; got none",
    )


def _typed_list(items, kind: type, name: str, what: str, if_empty: str) -> list:
    """The items as a list, each an instance of ``kind``: ValueError
    ``if_empty`` for none, TypeError "<name>[k] must be <what>; got <type>"
    for the first that is not."""
    out = list(items)
    if not out:
        raise ValueError(if_empty)
    for k, o in enumerate(out):
        if not isinstance(o, kind):
            raise TypeError(f"{name}[{k}] must be {what}; got {type(o).__name__}")
    return out


def warm_optics_radiance(
    optics, lens_temperature_K, filter_temperature_K, reflected_temperature_K=0.0
) -> np.ndarray:
    """W [W/(m2 sr)] of every channel: shape ``temperatures' shape + (C,)``.

    Add it to the band radiances a forward model returns
    (``qogi.band_radiance(...) + warm_optics_radiance(optics, T_l, T_f)``) to
    get what the camera measures, when the forward model's channels are the
    optics' responses (``[o.response for o in optics]``).
    """
    opt = _optics_list(optics)
    parts = [
        np.asarray(
            o.warm_radiance(lens_temperature_K, filter_temperature_K, reflected_temperature_K)
        )
        for o in opt
    ]
    return np.stack(parts, axis=-1)


def _warm_term(
    optics,
    values: np.ndarray,
    name: str,
    axis: int,
    lens_temperature_K,
    filter_temperature_K,
    reflected_temperature_K,
):
    """W shaped to broadcast against ``values`` (channels on ``axis``), which
    must hold one channel per optics (ValueError naming ``name`` otherwise)."""
    opt = _optics_list(optics)
    shape_ndim = values.ndim
    if not -shape_ndim <= axis < shape_ndim:
        raise ValueError(f"axis {axis} is out of range for an array of {shape_ndim} dims")
    ax = axis - shape_ndim if axis >= 0 else axis
    w = warm_optics_radiance(opt, lens_temperature_K, filter_temperature_K, reflected_temperature_K)
    if values.shape[ax] != len(opt):
        raise ValueError(
            f"{name} has {values.shape[ax]} channels on axis {axis}; {len(opt)} optics were given"
        )
    return w.reshape(w.shape + (1,) * (-ax - 1))


def add_warm_optics(
    radiance,
    optics,
    lens_temperature_K,
    filter_temperature_K,
    reflected_temperature_K=0.0,
    *,
    axis: int = -3,
) -> np.ndarray:
    """Forward: band radiance through the channel responses -> what the
    detector measures, ``L + W(T_lens, T_filter, T_refl)``.

    Parameters
    ----------
    radiance : array, W/(m2 sr)
        Channel on ``axis`` (default -3: frames (..., C, H, W); use -1 for a
        vector of band radiances).
    optics : ChannelOptics or list of them, one per channel
    lens_temperature_K, filter_temperature_K, reflected_temperature_K : float or array, K
        One value, or an array matching the dimensions before the channel
        axis (e.g. one temperature per frame).
    """
    a = np.asarray(radiance)
    w = _warm_term(
        optics,
        a,
        "radiance",
        axis,
        lens_temperature_K,
        filter_temperature_K,
        reflected_temperature_K,
    )
    out = a + w
    return out.astype(a.dtype, copy=False) if a.dtype == np.float32 else out


def correct_warm_optics(
    measured,
    optics,
    lens_temperature_K,
    filter_temperature_K,
    reflected_temperature_K=0.0,
    *,
    reference_lens_temperature_K=None,
    reference_filter_temperature_K=None,
    axis: int = -3,
) -> np.ndarray:
    """Correction: remove the warm-optics radiance, ``L = L_meas - W``.

    When the measured radiance comes from a calibration made with the whole
    camera (lens and filter in place) in front of the blackbody, the fitted
    offset already holds W at the optics temperatures during calibration;
    then give those as ``reference_lens_temperature_K`` /
    ``reference_filter_temperature_K`` and only the drift
    ``W(T) - W(T_ref)`` is removed.

    Parameters as in :func:`add_warm_optics`.
    """
    a = np.asarray(measured)
    w = _warm_term(
        optics,
        a,
        "measured",
        axis,
        lens_temperature_K,
        filter_temperature_K,
        reflected_temperature_K,
    )
    if (reference_lens_temperature_K is None) != (reference_filter_temperature_K is None):
        raise ValueError(
            "give both reference_lens_temperature_K and reference_filter_temperature_K, or neither"
        )
    if reference_lens_temperature_K is not None:
        w_ref = _warm_term(
            optics,
            a,
            "measured",
            axis,
            reference_lens_temperature_K,
            reference_filter_temperature_K,
            reflected_temperature_K,
        )
        w = w - w_ref
    out = a - w
    return out.astype(a.dtype, copy=False) if a.dtype == np.float32 else out
