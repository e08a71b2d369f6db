"""Recordings: radiometric video of a scene, with its camera and scene metadata.

A :class:`Recording` is the interchange object between cameras, the synthetic
generator, the API, the CLI and the viewer. On disk it is one HDF5 file laid
out as the recording contract (``docs/recording.md``):

==========================  ====================================================
``/`` attrs                 ``format="qogi-recording"``, ``version=1``
``/frames``                 float32 (T, C, H, W), attr ``quantity`` =
                            ``"radiance"`` [W/(m2 sr)] or
                            ``"radiometric_temperature"`` [K]
``/time_s``                 float64 (T,), strictly increasing frame times [s]
``/camera`` attrs           ``name``, ``ifov_rad``, ``frame_rate_hz``,
                            optional ``netd_K``
``/camera/channels/<k>``    datasets ``wavenumber_cm1``, ``response``; attr
                            ``name`` (k = 0 .. C-1)
``/scene`` attrs            ``distance_m``, ``ambient_temperature_K``,
                            ``pressure_Pa``; optional ``wind_speed_m_s``,
                            ``gas_temperature_K``, ``background_temperature_K``,
                            ``species``
``/truth`` (synthetic)      attrs ``emission_rate_kg_s_<SPECIES>``; optional
                            datasets
==========================  ====================================================

:func:`open_recording` validates everything before returning (and by default
scans every frame for NaN/inf, streaming, without holding the video in
memory); frames are then read lazily, per frame or per range.
:class:`RecordingWriter` appends frames one by one, for generators.

Band radiance and radiometric temperature are converted into each other
through each channel's response (:mod:`qogi.radiometry`), so any reader can
ask for the quantity it needs whatever the file stores.
"""

from __future__ import annotations

import contextlib
import errno
import io
import math
import os
import re
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from .errors import DataError, is_no_space
from .optics import SpectralResponse, channel_problem
from .radiometry import band_table

__all__ = [
    "FORMAT",
    "VERSION",
    "QUANTITIES",
    "RANGES",
    "FRAME_RATE_TOLERANCE",
    "typical_interval",
    "RecordingError",
    "Camera",
    "Scene",
    "Truth",
    "Recording",
    "RecordingWriter",
    "open_recording",
    "write_recording",
]

FORMAT = "qogi-recording"
VERSION = 1
#: Frame quantities and their units.
QUANTITIES = {"radiance": "W/(m2 sr)", "radiometric_temperature": "K"}
#: Accepted closed ranges [low, high] of scalar metadata (a value must be
#: finite; "low" is exclusive where marked by the error message). One table so
#: that the docs, the checks and the messages agree.
RANGES = {
    "camera.ifov_rad": (0.0, 0.1, "rad", "exclusive_low"),
    "camera.frame_rate_hz": (0.0, 1e5, "Hz", "exclusive_low"),
    "camera.netd_K": (0.0, 10.0, "K", "exclusive_low"),
    "scene.distance_m": (0.0, 1e5, "m", "exclusive_low"),
    "scene.ambient_temperature_K": (180.0, 350.0, "K", ""),
    "scene.pressure_Pa": (3.0e4, 1.1e5, "Pa", ""),
    "scene.wind_speed_m_s": (0.0, 100.0, "m/s", ""),
    "scene.gas_temperature_K": (150.0, 2500.0, "K", ""),
    "scene.background_temperature_K": (10.0, 2500.0, "K", ""),
    "truth.emission_rate_kg_s": (0.0, 1e6, "kg/s", ""),
}
#: /camera frame_rate_hz must match 1 / typical_interval(time_s) within this
#: relative tolerance, or opening fails: time_s is what the pipeline uses, and
#: a file whose two clocks disagree by more is ambiguous. (Dropped frames and
#: jitter are fine: see typical_interval.)
FRAME_RATE_TOLERANCE = 0.01

_SPECIES_RE = re.compile(r"^[A-Za-z][A-Za-z0-9]*$")
_MEMORY = "<in memory>"


class RecordingError(DataError):
    """A recording that does not follow the contract (a
    :class:`qogi.errors.DataError`, hence a ValueError; exit 3 on the command line).

    The message names the file, the dataset or attribute, the offending value,
    the expected form and how to fix it. The parts are also attributes:
    ``path``, ``location``, ``problem``, ``fix``.
    """

    def __init__(self, path: str, location: str, problem: str, fix: str = ""):
        self.path, self.location, self.problem, self.fix = path, location, problem, fix
        msg = f"{path}: {location}: {problem}"
        if fix:
            msg += f". Fix: {fix}"
        super().__init__(msg)


def _check_channels(channels, path: str, num_frame_channels: Optional[int] = None) -> None:
    """:func:`qogi.optics.channel_problem` as a RecordingError at /camera/channels."""
    bad = channel_problem(channels, num_frame_channels)
    if bad is not None:
        raise RecordingError(path, "/camera/channels" + bad[0], bad[1], bad[2])


def _check_range(key: str, value, path: str, location: str, fix: str = "") -> float:
    lo, hi, unit, mode = RANGES[key]
    name = key.split(".", 1)[1]
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RecordingError(
            path, location, f"{name} must be a number [{unit}]; got {value!r}", fix
        ) from None
    low_ok = v > lo if mode == "exclusive_low" else v >= lo
    if not (math.isfinite(v) and low_ok and v <= hi):
        interval = f"({lo:g}, {hi:g}]" if mode == "exclusive_low" else f"[{lo:g}, {hi:g}]"
        raise RecordingError(
            path,
            location,
            f"{name} = {v!r} {unit} is outside the accepted range {interval} {unit}",
            fix,
        )
    return v


# --------------------------------------------------------------------------- metadata


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

    def validate(self, path: str = _MEMORY) -> None:
        """Raise :class:`RecordingError` unless every field is in range."""
        if not isinstance(self.name, str):
            raise RecordingError(path, "/camera attr name", f"must be a string; got {self.name!r}")
        _check_range(
            "camera.ifov_rad",
            self.ifov_rad,
            path,
            "/camera attr ifov_rad",
            "give the angular size of one pixel in radians "
            "(horizontal field of view / pixels across)",
        )
        if self.frame_rate_hz is not None:
            _check_range(
                "camera.frame_rate_hz", self.frame_rate_hz, path, "/camera attr frame_rate_hz"
            )
        if self.netd_K is not None:
            _check_range("camera.netd_K", self.netd_K, path, "/camera attr netd_K")
        _check_channels(self.channels, path)


@dataclass
class Scene:
    """Where and in what conditions the video was taken.

    Attributes
    ----------
    distance_m : float, m
        Camera-to-plume distance, in (0, 1e5].
    ambient_temperature_K : float, K
        Ambient air temperature, in [180, 350].
    pressure_Pa : float, Pa
        Ambient pressure, in [3e4, 1.1e5].
    wind_speed_m_s : float or None, m/s
        Optional, in [0, 100].
    gas_temperature_K : float or None, K
        Optional, in [150, 2500].
    background_temperature_K : float or None, K
        Optional (radiometric temperature of the background), in [10, 2500].
    species : tuple of str
        Gas species expected in the plume (HITRAN names, e.g. ``("CH4",)``).
    """

    distance_m: float
    ambient_temperature_K: float
    pressure_Pa: float
    wind_speed_m_s: Optional[float] = None
    gas_temperature_K: Optional[float] = None
    background_temperature_K: Optional[float] = None
    species: Tuple[str, ...] = ()

    def validate(self, path: str = _MEMORY) -> None:
        """Raise :class:`RecordingError` unless every field is in range."""
        for name in ("distance_m", "ambient_temperature_K", "pressure_Pa"):
            _check_range(f"scene.{name}", getattr(self, name), path, f"/scene attr {name}")
        for name in ("wind_speed_m_s", "gas_temperature_K", "background_temperature_K"):
            v = getattr(self, name)
            if v is not None:
                _check_range(f"scene.{name}", v, path, f"/scene attr {name}")
        for s in self.species:
            if not isinstance(s, str) or not _SPECIES_RE.match(s):
                raise RecordingError(
                    path,
                    "/scene attr species",
                    f"species name {s!r} is not a molecule name",
                    "use HITRAN molecule names such as CH4, CO2, C2H6",
                )


@dataclass
class Truth:
    """Ground truth of a synthetic recording.

    Attributes
    ----------
    emission_rate_kg_s : dict of str -> float, kg/s
        True emission rate per species.
    datasets : dict of str -> array
        Optional arrays (e.g. column density maps). For a recording opened
        from a file these are h5py datasets, read lazily (slice them or pass
        them to ``np.asarray``).
    attrs : dict
        Any other attributes of ``/truth``.
    """

    emission_rate_kg_s: Dict[str, float] = field(default_factory=dict)
    datasets: Dict[str, Any] = field(default_factory=dict)
    attrs: Dict[str, object] = field(default_factory=dict)

    def validate(self, path: str = _MEMORY) -> None:
        for sp, rate in self.emission_rate_kg_s.items():
            if not _SPECIES_RE.match(str(sp)):
                raise RecordingError(
                    path,
                    f"/truth attr emission_rate_kg_s_{sp}",
                    f"species name {sp!r} is not a molecule name",
                )
            _check_range(
                "truth.emission_rate_kg_s", rate, path, f"/truth attr emission_rate_kg_s_{sp}"
            )


# --------------------------------------------------------------------------- frames


def _first_nonfinite(block: np.ndarray) -> Tuple[int, ...]:
    return tuple(int(v) for v in np.argwhere(~np.isfinite(block))[0])


class Recording:
    """Radiometric video with its camera, scene and (for synthetic data) truth.

    Do not call the constructor: use :func:`open_recording` (a file, read
    lazily), :meth:`from_arrays` (numpy arrays) or a reader in :mod:`qogi.io`.

    Frames are (C, H, W) float32 images, one per time in :attr:`time_s`; the
    stored :attr:`quantity` is ``"radiance"`` [W/(m2 sr)] or
    ``"radiometric_temperature"`` [K]. Every frame accessor takes
    ``quantity=`` to convert through the channel responses on the fly.

    Invalid pixels: with ``nonfinite="invalid"`` (see :func:`open_recording`)
    NaN/inf pixels are returned as NaN and counted in :attr:`n_invalid`;
    with the default ``"error"`` a recording containing any is refused.
    """

    def __init__(
        self,
        *,
        source,
        time_s: np.ndarray,
        quantity: str,
        camera: Camera,
        scene: Scene,
        truth: Optional[Truth],
        path: str,
        nonfinite: str,
        h5file=None,
        attrs: Optional[dict] = None,
    ):
        self._source = source  # ndarray or h5py.Dataset, (T, C, H, W)
        self._h5 = h5file
        self.time_s = time_s
        self.quantity = quantity
        self.camera = camera
        self.scene = scene
        self.truth = truth
        self.path = path
        self.nonfinite = nonfinite
        self.attrs = dict(attrs or {})
        #: Number of non-finite (invalid) pixel values found by the scan on
        #: open, or None if the frames were not scanned.
        self.n_invalid: Optional[int] = None

    # ----------------------------------------------------------------- construction
    @classmethod
    def from_arrays(
        cls,
        frames,
        time_s=None,
        *,
        quantity: str,
        camera: Camera,
        scene: Scene,
        truth: Optional[Truth] = None,
        nonfinite: str = "error",
    ) -> Recording:
        """Build a recording in memory from numpy arrays.

        Parameters
        ----------
        frames : array (T, C, H, W), or (T, H, W) for one channel
            Band radiance [W/(m2 sr)] or radiometric temperature [K]; stored
            as float32.
        time_s : array (T,), s, optional
            Strictly increasing frame times. Default: ``arange(T) /
            camera.frame_rate_hz``.
        quantity : {"radiance", "radiometric_temperature"}
        camera : Camera
            With one channel response per frame channel.
            ``camera.frame_rate_hz=None`` takes it from ``time_s``.
        scene : Scene
        truth : Truth, optional
        nonfinite : {"error", "invalid"}
            What NaN/inf pixels are: an error (default) or invalid pixels.

        Raises
        ------
        RecordingError
            Naming the problem and the fix, as :func:`open_recording`.
        """
        a = np.asarray(frames)
        if a.ndim == 3:
            a = a[:, None]
        if not (np.issubdtype(a.dtype, np.floating) or np.issubdtype(a.dtype, np.integer)):
            raise RecordingError(
                _MEMORY,
                "frames",
                f"dtype {a.dtype} is not numeric",
                "pass band radiance or radiometric temperature as numbers",
            )
        a = np.ascontiguousarray(a, dtype=np.float32)
        if a.ndim != 4:
            raise RecordingError(
                _MEMORY,
                "frames",
                f"expected shape (T, C, H, W) or (T, H, W); got {a.shape}",
                "stack frames as (time, channel, height, width)",
            )
        if time_s is None:
            if camera.frame_rate_hz is None:
                raise RecordingError(
                    _MEMORY,
                    "time_s",
                    "neither time_s nor camera.frame_rate_hz was given",
                    "pass time_s (s) or set camera.frame_rate_hz",
                )
            _check_range(
                "camera.frame_rate_hz", camera.frame_rate_hz, _MEMORY, "camera.frame_rate_hz"
            )
            time_s = np.arange(a.shape[0], dtype=np.float64) / float(camera.frame_rate_hz)
        t = np.asarray(time_s, dtype=np.float64)
        cam = Camera(
            camera.name, camera.ifov_rad, list(camera.channels), camera.frame_rate_hz, camera.netd_K
        )
        _validate_time(_MEMORY, t, a.shape[0], "time_s")
        if cam.frame_rate_hz is None:
            cam.frame_rate_hz = _frame_rate_from_times(t)
        rec = cls(
            source=a,
            time_s=t,
            quantity=quantity,
            camera=cam,
            scene=scene,
            truth=truth,
            path=_MEMORY,
            nonfinite=nonfinite,
        )
        rec._validate_metadata()
        rec._scan_frames()
        return rec

    # ----------------------------------------------------------------- shape
    @property
    def shape(self) -> Tuple[int, int, int, int]:
        """(T, C, H, W)."""
        t, c, h, w = (int(s) for s in self._source.shape)
        return t, c, h, w

    @property
    def n_frames(self) -> int:
        return self.shape[0]

    @property
    def n_channels(self) -> int:
        return self.shape[1]

    @property
    def height(self) -> int:
        return self.shape[2]

    @property
    def width(self) -> int:
        return self.shape[3]

    @property
    def channels(self) -> List[SpectralResponse]:
        """The camera's channel responses (``camera.channels``)."""
        return self.camera.channels

    @property
    def unit(self) -> str:
        """Unit of the stored quantity."""
        return QUANTITIES[self.quantity]

    @property
    def duration_s(self) -> float:
        """Time from the first to the last frame plus one frame interval [s]."""
        if self.n_frames == 0:
            return 0.0
        rate = self.camera.frame_rate_hz
        assert rate is not None  # filled from time_s when a recording is opened or made
        return float(self.time_s[-1] - self.time_s[0]) + 1.0 / float(rate)

    @property
    def in_memory(self) -> bool:
        return isinstance(self._source, np.ndarray)

    def __len__(self) -> int:
        return self.n_frames

    def __repr__(self) -> str:
        t, c, h, w = self.shape
        return (
            f"Recording({self.path!r}, {t} frames x {c} channels x {h}x{w}, "
            f"{self.quantity} [{self.unit}], {self.camera.frame_rate_hz:g} Hz)"
        )

    # ----------------------------------------------------------------- frames
    def frames(
        self, start: int = 0, stop: Optional[int] = None, quantity: Optional[str] = None
    ) -> np.ndarray:
        """Frames ``start:stop`` as a float32 array (n, C, H, W).

        ``quantity`` (default: the stored one) converts through the channel
        responses: ``"radiance"`` [W/(m2 sr)] or ``"radiometric_temperature"`` [K].
        """
        n = self.n_frames
        stop = n if stop is None else stop
        if not (0 <= start <= stop <= n):
            raise IndexError(f"frame range {start}:{stop} is outside 0:{n}")
        try:
            block = np.asarray(self._source[start:stop], dtype=np.float32)
        except Exception as e:  # h5py's errors on a damaged chunk or type
            if self.path == _MEMORY or isinstance(e, DataError):
                raise
            raise _damaged(self.path, e) from e
        block = self._apply_nonfinite(block, start)
        return self._convert(block, quantity)

    def frame(self, index: int, quantity: Optional[str] = None) -> np.ndarray:
        """Frame ``index`` (negative counts from the end) as float32 (C, H, W)."""
        n = self.n_frames
        i = index + n if index < 0 else index
        if not 0 <= i < n:
            raise IndexError(f"frame {index} is outside 0..{n - 1}")
        return self.frames(i, i + 1, quantity)[0]

    def __iter__(self) -> Iterator[np.ndarray]:
        return self.iter_frames()

    def iter_frames(
        self, start: int = 0, stop: Optional[int] = None, quantity: Optional[str] = None
    ) -> Iterator[np.ndarray]:
        """Yield frames one by one, (C, H, W) float32, reading each when needed."""
        stop = self.n_frames if stop is None else stop
        for i in range(start, stop):
            yield self.frames(i, i + 1, quantity)[0]

    def iter_batches(
        self, batch_size: int, quantity: Optional[str] = None
    ) -> Iterator[Tuple[int, np.ndarray]]:
        """Yield ``(start, frames)`` blocks of up to ``batch_size`` frames."""
        if int(batch_size) < 1:
            raise ValueError(f"batch_size must be >= 1; got {batch_size}")
        for s in range(0, self.n_frames, int(batch_size)):
            yield s, self.frames(s, min(s + int(batch_size), self.n_frames), quantity)

    def to_array(self, quantity: Optional[str] = None) -> np.ndarray:
        """All frames as one float32 array (T, C, H, W) (loads the whole video)."""
        return self.frames(0, self.n_frames, quantity)

    def load(self) -> Recording:
        """An in-memory copy (all frames read); the file can then be closed."""
        rec = Recording(
            source=self.to_array(),
            time_s=self.time_s.copy(),
            quantity=self.quantity,
            camera=self.camera,
            scene=self.scene,
            truth=_load_truth(self.truth),
            path=self.path,
            nonfinite=self.nonfinite,
            attrs=self.attrs,
        )
        rec.n_invalid = self.n_invalid
        return rec

    def _convert(self, block: np.ndarray, quantity: Optional[str]) -> np.ndarray:
        if quantity is None or quantity == self.quantity:
            return block
        if quantity not in QUANTITIES:
            raise ValueError(f"quantity must be one of {sorted(QUANTITIES)}; got {quantity!r}")
        out = np.empty_like(block)
        for k, ch in enumerate(self.channels):
            table = band_table(ch)
            try:
                if quantity == "radiance":
                    out[:, k] = table.radiance(block[:, k])
                else:
                    out[:, k] = table.temperature(block[:, k])
            except ValueError as e:  # values no blackbody gives (zero, negative radiance)
                if isinstance(e, DataError):
                    raise
                raise RecordingError(
                    self.path,
                    f"/frames channel {k}",
                    f"cannot be converted to {quantity}: {e}",
                    "check the frames' quantity and values",
                ) from None
        return out

    def _apply_nonfinite(self, block: np.ndarray, start: int) -> np.ndarray:
        # A finite sum (in float64: no overflow) means every value is finite.
        if np.isfinite(block.sum(dtype=np.float64)):
            return block
        bad = ~np.isfinite(block)
        if self.nonfinite == "invalid":
            block[bad] = np.nan
            return block
        first = _first_nonfinite(block)
        raise RecordingError(
            self.path,
            "/frames",
            f"{int(bad.sum())} non-finite values in frames {start}..{start + len(block) - 1}, "
            f"the first at (t={first[0] + start}, c={first[1]}, y={first[2]}, x={first[3]}) = "
            f"{block[first]!r}",
            "open with nonfinite='invalid' to treat them as invalid pixels",
        )

    # ----------------------------------------------------------------- checks
    def _validate_metadata(self) -> None:
        path = self.path
        t, c, h, w = self.shape
        if self.quantity not in QUANTITIES:
            raise RecordingError(
                path,
                "/frames attr quantity",
                f"unknown quantity {self.quantity!r}",
                f"use one of {sorted(QUANTITIES)} "
                "(band radiance in W/(m2 sr) or radiometric temperature in K)",
            )
        if self.nonfinite not in ("error", "invalid"):
            raise ValueError(f"nonfinite must be 'error' or 'invalid'; got {self.nonfinite!r}")
        if t < 1 or h < 1 or w < 1:
            raise RecordingError(
                path,
                "/frames",
                f"empty frames, shape {self.shape}",
                "a recording needs at least one frame of at least 1x1 pixel",
            )
        self.camera.validate(path)
        self.scene.validate(path)
        if self.truth is not None:
            self.truth.validate(path)
        _check_channels(self.camera.channels, path, c)
        _check_frame_rate(path, self.time_s, self.camera.frame_rate_hz)

    def _scan_frames(self, batch_bytes: int = 64 << 20) -> None:
        """Count non-finite values over all frames, streaming; raise or record."""
        t, c, h, w = self.shape
        per_frame = max(1, c * h * w * 4)
        step = max(1, batch_bytes // per_frame)
        total, first = 0, None
        for s in range(0, t, step):
            block = np.asarray(self._source[s : s + step])
            bad = ~np.isfinite(block)
            nbad = int(np.count_nonzero(bad))
            if nbad:
                if first is None:
                    loc = _first_nonfinite(block)
                    first = (loc[0] + s,) + loc[1:], block[loc]
                total += nbad
        self.n_invalid = total
        if total and self.nonfinite == "error":
            assert first is not None  # set with the first non-finite block
            (ti, ci, yi, xi), val = first
            raise RecordingError(
                self.path,
                "/frames",
                f"{total} non-finite values (NaN/inf) out of {t * c * h * w}; the first at "
                f"(t={ti}, c={ci}, y={yi}, x={xi}) = {val!r}",
                "open with nonfinite='invalid' to treat them as invalid pixels "
                "(they are then returned as NaN and counted), or repair the frames",
            )

    # ----------------------------------------------------------------- output
    def save(
        self,
        path: Union[str, os.PathLike],
        *,
        compression: Optional[str] = None,
        compression_level: Optional[int] = None,
        overwrite: bool = True,
    ) -> None:
        """Write this recording to ``path`` (see :func:`write_recording`)."""
        write_recording(
            path,
            self,
            compression=compression,
            compression_level=compression_level,
            overwrite=overwrite,
        )

    def close(self) -> None:
        """Close the file of a recording opened with :func:`open_recording`."""
        if self._h5 is not None:
            self._h5.close()
            self._h5 = None

    def __enter__(self) -> Recording:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def summary(self) -> dict:
        """A JSON-ready description: camera, channels, frames, scene, truth."""
        t, c, h, w = self.shape
        out: Dict[str, Any] = {
            "path": self.path,
            "format": FORMAT,
            "version": VERSION,
            "camera": {
                "name": self.camera.name,
                "ifov_rad": self.camera.ifov_rad,
                "frame_rate_hz": self.camera.frame_rate_hz,
                "netd_K": self.camera.netd_K,
            },
            "channels": [
                {
                    "index": k,
                    "name": ch.name,
                    "band_cm1": [float(ch.nu_cm1[0]), float(ch.nu_cm1[-1])],
                    "band_um": [1e4 / float(ch.nu_cm1[-1]), 1e4 / float(ch.nu_cm1[0])],
                    "half_max_cm1": list(_half_max_band(ch)),
                    "centroid_cm1": float(ch.centroid_cm1),
                    "centroid_um": 1e4 / float(ch.centroid_cm1),
                }
                for k, ch in enumerate(self.channels)
            ],
            "frames": {
                "T": t,
                "C": c,
                "H": h,
                "W": w,
                "quantity": self.quantity,
                "unit": self.unit,
                "duration_s": self.duration_s,
                "time_first_s": float(self.time_s[0]),
                "time_last_s": float(self.time_s[-1]),
                "n_invalid": self.n_invalid,
            },
            "scene": {
                k: getattr(self.scene, k)
                for k in (
                    "distance_m",
                    "ambient_temperature_K",
                    "pressure_Pa",
                    "wind_speed_m_s",
                    "gas_temperature_K",
                    "background_temperature_K",
                )
            },
        }
        out["scene"]["species"] = list(self.scene.species)
        if self.truth is not None:
            out["truth"] = {
                "emission_rate_kg_s": dict(self.truth.emission_rate_kg_s),
                "emission_rate_kg_h": {
                    k: v * 3600.0 for k, v in self.truth.emission_rate_kg_s.items()
                },
                "datasets": {k: list(np.shape(v)) for k, v in self.truth.datasets.items()},
            }
        return out


def _half_max_band(ch: SpectralResponse) -> Tuple[float, float]:
    """Outermost wavenumbers [cm-1] where the response crosses half its maximum
    (linear interpolation between samples)."""
    nu, r = np.asarray(ch.nu_cm1), np.asarray(ch.response)
    half = 0.5 * r.max()
    above = np.flatnonzero(r >= half)
    i, j = int(above[0]), int(above[-1])

    def cross(a, b):
        if r[a] == r[b]:
            return float(nu[a])
        return float(nu[a] + (half - r[a]) * (nu[b] - nu[a]) / (r[b] - r[a]))

    lo = cross(i - 1, i) if i > 0 else float(nu[0])
    hi = cross(j, j + 1) if j < len(nu) - 1 else float(nu[-1])
    return lo, hi


def _load_truth(truth: Optional[Truth]) -> Optional[Truth]:
    if truth is None:
        return None
    return Truth(
        dict(truth.emission_rate_kg_s),
        {k: np.asarray(v) for k, v in truth.datasets.items()},
        dict(truth.attrs),
    )


def _validate_time(path: str, t: np.ndarray, n_frames: int, location: str = "/time_s") -> None:
    if t.ndim != 1 or t.shape[0] != n_frames:
        raise RecordingError(
            path,
            location,
            f"expected shape ({n_frames},) to match the {n_frames} frames; got {t.shape}",
            "write one time [s] per frame",
        )
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise RecordingError(
            path,
            location,
            f"{bad.size} non-finite times, the first at index {bad[0]} ({t[bad[0]]!r})",
            "write finite frame times in seconds",
        )
    if n_frames > 1:
        d = np.diff(t)
        bad = np.flatnonzero(d <= 0)
        if bad.size:
            i = int(bad[0])
            raise RecordingError(
                path,
                location,
                f"times must be strictly increasing; time_s[{i}] = {t[i]!r} "
                f"and time_s[{i + 1}] = {t[i + 1]!r} "
                f"({bad.size} such steps)",
                "sort the frames by time and drop duplicates",
            )


def typical_interval(time_s) -> float:
    """The typical frame interval [s] of increasing frame times: the mean of
    the intervals within +-50% of the median one. Robust to dropped frames
    (longer intervals) and to time stamps quantized to e.g. 1 ms (a 30 Hz
    camera stamping 33 and 34 ms intervals), where the plain median is off
    by up to one quantum."""
    d = np.diff(np.asarray(time_s, dtype=np.float64))
    m = float(np.median(d))
    near = d[(d > 0.5 * m) & (d < 1.5 * m)]
    return float(near.mean()) if near.size else m


def _frame_rate_from_times(t: np.ndarray) -> float:
    if t.size < 2:
        raise RecordingError(
            _MEMORY,
            "camera.frame_rate_hz",
            "cannot infer the frame rate from a single frame time",
            "set camera.frame_rate_hz",
        )
    return 1.0 / typical_interval(t)


def _check_frame_rate(path: str, t: np.ndarray, frame_rate_hz: Optional[float]) -> None:
    if frame_rate_hz is None:
        raise RecordingError(
            path, "/camera attr frame_rate_hz", "missing", "write the camera frame rate in Hz"
        )
    if t.size < 2:
        return
    measured = 1.0 / typical_interval(t)
    if abs(measured - frame_rate_hz) > FRAME_RATE_TOLERANCE * frame_rate_hz:
        raise RecordingError(
            path,
            "/camera attr frame_rate_hz",
            f"frame_rate_hz = {frame_rate_hz:g} Hz disagrees with /time_s, whose typical frame "
            f"interval {1.0 / measured:.6g} s means {measured:.6g} Hz "
            f"(tolerance {FRAME_RATE_TOLERANCE:.0%})",
            "correct frame_rate_hz or time_s (time_s is what the pipeline uses)",
        )


# --------------------------------------------------------------------------- HDF5 I/O


def _h5py():
    import h5py

    return h5py


class GuardedFile(io.RawIOBase):
    """The file HDF5 writes a recording through (h5py's ``fileobj`` driver).

    A failed write (a full disk, a quota) is kept in :attr:`error` and every
    later write is dropped, so HDF5 itself never sees one fail. HDF5 that
    sees a write fail while it flushes its caches (at close, on a full disk)
    leaves the file open inside the library in a state in which closing it
    fails and the interpreter's exit crashes (SIGSEGV); through this file
    the close completes and :meth:`check` raises the write's error, after
    which the file is deleted (it is a temporary one,
    :func:`qogi.files.atomic_path`).
    """

    def __init__(self, path: Union[str, os.PathLike], mode: str = "w"):
        super().__init__()
        self._fh = open(path, "w+b" if mode == "w" else "r+b", buffering=0)  # noqa: SIM115
        self.error: Optional[OSError] = None

    def readable(self) -> bool:
        return True

    def writable(self) -> bool:
        return True

    def seekable(self) -> bool:
        return True

    def seek(self, pos: int, whence: int = 0) -> int:
        return self._fh.seek(pos, whence)

    def tell(self) -> int:
        return self._fh.tell()

    def readinto(self, b) -> int:
        return self._fh.readinto(b)

    def write(self, b) -> int:
        n = memoryview(b).nbytes
        if self.error is None:
            try:
                done = self._fh.write(b)
                if done == n:
                    return n
                raise OSError(errno.ENOSPC, f"short write ({done} of {n} bytes)")
            except OSError as e:
                self.error = e
        self._fh.seek(n, 1)
        return n

    def truncate(self, size: Optional[int] = None) -> int:
        if self.error is None:
            try:
                return self._fh.truncate(size)
            except OSError as e:
                self.error = e
        return self._fh.tell() if size is None else size

    def flush(self) -> None:
        pass  # unbuffered: every write has reached the OS

    def close(self) -> None:
        if not self.closed:
            self._fh.close()
        super().close()

    def check(self) -> None:
        """Raises the first failed write's error (an OSError), if any."""
        if self.error is not None:
            raise self.error


@contextlib.contextmanager
def h5_writing(path: Union[str, os.PathLike], mode: str = "w"):
    """``h5py.File`` written through a :class:`GuardedFile`: a full disk is
    an OSError (ENOSPC) when the block ends, never a file HDF5 cannot close.
    ``mode`` "w" (create) or "a" (change an existing file)."""
    sink = GuardedFile(path, mode)
    try:
        f = _h5py().File(sink, "w" if mode == "w" else "r+")
    except BaseException:
        sink.close()
        raise
    try:
        yield f
    finally:
        try:
            f.close()
        finally:
            sink.close()
    sink.check()


#: Largest attribute or metadata dataset (channel responses, truth) read whole [bytes].
_MAX_METADATA_BYTES = 64 << 20


def set_attr(obj, name: str, value) -> None:
    """Writes an HDF5 attribute the way recordings store them: text as
    fixed-length UTF-8 (a string or a sequence of strings), anything else as
    given. Variable-length strings, h5py's default for ``str``, keep their
    bytes on a global heap whose forged lengths can send libhdf5 into an
    unbounded read; fixed-length ones are read whole after their declared
    size is checked (see :func:`_check_variable_length`)."""
    h5py = _h5py()
    if isinstance(value, str):
        b = value.encode("utf-8")
        obj.attrs.create(name, np.array(b, dtype=h5py.string_dtype("utf-8", max(1, len(b)))))
        return
    if (
        isinstance(value, (list, tuple, np.ndarray))
        and len(value)
        and all(isinstance(v, (str, np.str_)) for v in np.ravel(np.asarray(value, dtype=object)))
    ):
        enc = [str(v).encode("utf-8") for v in np.ravel(np.asarray(value, dtype=object))]
        n = max([1, *(len(b) for b in enc)])
        arr = np.array(enc, dtype=h5py.string_dtype("utf-8", n)).reshape(np.shape(value))
        obj.attrs.create(name, arr)
        return
    obj.attrs[name] = value


#: Bounds for reading a file's variable-length attributes in a child process:
#: address space [bytes], CPU time [s] and wall time [s]. A real attribute
#: of a few names reads in microseconds; a forged heap length makes libhdf5
#: allocate gigabytes or loop without end (tests/data/fuzz/crashes).
_PROBE_MEMORY_BYTES = 2 << 30
_PROBE_CPU_S = 5
_PROBE_WALL_S = 120.0
_probed_ok: set = set()

# Run by a fresh interpreter (numpy + h5py only): reads each variable-length
# attribute named on the command line, printing which one before reading it.
_PROBE_CODE = """
import json, resource, sys
mem, cpu = int(sys.argv[2]), int(sys.argv[3])
resource.setrlimit(resource.RLIMIT_AS, (mem, mem))
resource.setrlimit(resource.RLIMIT_CPU, (cpu, cpu + 1))
import h5py
with h5py.File(sys.argv[1], "r") as f:
    for obj, name in json.loads(sys.argv[4]):
        print(obj, name, flush=True)
        f[obj].attrs[name]
print("ok", flush=True)
"""


def _is_variable_length(type_id) -> bool:
    h5t = _h5py().h5t
    if isinstance(type_id, h5t.TypeStringID):
        return bool(type_id.is_variable_str())
    try:
        return bool(type_id.detect_class(h5t.VLEN))
    except Exception:  # noqa: BLE001 - a type libhdf5 cannot classify: treat as unsafe
        return True


def _check_variable_length(f, p: str) -> None:
    """Reads the variable-length attributes of a recording's metadata objects
    (older qogi files and other writers store text that way) in a child
    process bounded in memory and CPU time, before this process touches
    them; a forged one raises RecordingError naming it instead of hanging or
    exhausting memory. Passed files are remembered (path, size, mtime)."""
    import json
    import subprocess
    import sys

    h5py = _h5py()
    items = []
    objects = ["/", "/frames", "/time_s", "/camera", "/scene", "/truth"]
    ch = f.get("/camera/channels")
    if isinstance(ch, h5py.Group):
        objects += [f"/camera/channels/{k}" for k in list(ch.keys())[:64]]
    for o in objects:
        obj = f.get(o)
        if obj is None:
            continue
        for k in obj.attrs:
            try:
                tid = obj.attrs.get_id(k).get_type()
            except Exception:  # noqa: BLE001 - unreadable type: the normal read reports it
                continue
            if _is_variable_length(tid):
                items.append((o, k))
    if not items:
        return
    st = os.stat(p)
    key = (os.path.realpath(p), st.st_size, st.st_mtime_ns, tuple(items))
    if key in _probed_ok:
        return
    env = {k: v for k, v in os.environ.items() if not k.startswith("PYTHON")}
    env["OPENBLAS_NUM_THREADS"] = env["OMP_NUM_THREADS"] = "1"
    try:
        r = subprocess.run(
            [
                sys.executable,
                "-I",
                "-c",
                _PROBE_CODE,
                p,
                str(_PROBE_MEMORY_BYTES),
                str(_PROBE_CPU_S),
                json.dumps(items),
            ],
            capture_output=True,
            check=False,  # the exit status is read below
            text=True,
            timeout=_PROBE_WALL_S,
            env=env,
            stdin=subprocess.DEVNULL,
        )
        out, ok = r.stdout.split(), r.returncode == 0 and r.stdout.rstrip().endswith("ok")
        why = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
        if r.returncode < 0:
            why = {9: "killed at the CPU-time limit", 24: "stopped at the CPU-time limit"}.get(
                -r.returncode, f"killed by signal {-r.returncode}"
            )
    except subprocess.TimeoutExpired as e:
        out, ok, why = (e.stdout or b"").decode(errors="replace").split(), False, "timed out"
    if ok:
        _probed_ok.add(key)
        return
    where = f"{out[-2]} attr {out[-1]}" if len(out) >= 2 else "variable-length attributes"
    raise RecordingError(
        p,
        where,
        f"cannot be read within {_PROBE_MEMORY_BYTES >> 30} GiB and "
        f"{_PROBE_CPU_S} s of CPU ({why})",
        "the file is damaged or forged; write it again (qogi writes text "
        "attributes as fixed-length strings)",
    )


def _small(ds, path: str, location: str) -> np.ndarray:
    """A metadata dataset read whole, after checking its declared size."""
    size = int(ds.size) * int(ds.dtype.itemsize)
    if size > _MAX_METADATA_BYTES:
        raise RecordingError(
            path,
            location,
            f"shape {ds.shape} declares {size / 2**20:.3g} MiB of metadata",
            "the file is damaged or forged",
        )
    return ds[()]


def _attr(obj, name: str, path: str, location: str, required: bool = True, fix: str = ""):
    if name not in obj.attrs:
        if required:
            raise RecordingError(
                path,
                f"{location} attr {name}",
                "missing",
                fix or f"add the attribute {name} to {location}",
            )
        return None
    try:
        size = int(obj.attrs.get_id(name).get_storage_size())
    except Exception:  # noqa: BLE001 - unreadable: reported by the read below
        size = 0
    if size > _MAX_METADATA_BYTES:
        raise RecordingError(
            path,
            f"{location} attr {name}",
            f"declares {size / 2**20:.3g} MiB (an attribute holds a few numbers or a name)",
            "the file is damaged or forged",
        )
    v = obj.attrs[name]
    if isinstance(v, bytes):
        v = v.decode("utf-8", "replace")
    if isinstance(v, np.ndarray) and v.dtype.kind == "S":  # fixed-length text
        v = np.char.decode(v, "utf-8", "replace")
    if isinstance(v, np.ndarray) and v.shape == ():
        v = v[()]
    if isinstance(v, np.generic):
        v = v.item()
    return v


def _species(value) -> Tuple[str, ...]:
    if value is None:
        return ()
    if isinstance(value, str):
        return tuple(s for s in re.split(r"[,\s]+", value) if s)
    return tuple(s.decode() if isinstance(s, bytes) else str(s) for s in np.ravel(value))


def open_recording(
    path: Union[str, os.PathLike], *, nonfinite: str = "error", check_frames: bool = True
) -> Recording:
    """Open a recording file, validate it, and read frames lazily.

    Parameters
    ----------
    path : str or path
        An HDF5 file following the recording contract (``docs/recording.md``).
    nonfinite : {"error", "invalid"}
        NaN/inf frame values: refuse the file (default; the error reports how
        many and where the first is) or treat them as invalid pixels
        (returned as NaN, counted in ``Recording.n_invalid``).
    check_frames : bool, default True
        Scan every frame for NaN/inf now (streaming: one read of the whole file,
        in blocks, so memory stays bounded). With False
        the check happens on each read instead (``nonfinite="error"`` then
        raises when a bad frame is read).

    Returns
    -------
    Recording
        Keeps the file open; use ``with open_recording(p) as rec:`` or
        ``rec.close()``.

    Raises
    ------
    RecordingError (a ValueError)
        Before any processing, naming the file, the dataset or attribute, the
        value, the expected form and the fix: missing file or not HDF5, wrong
        format/version, missing or mis-shaped /frames or /time_s, non-monotonic
        times, unknown quantity, missing or invalid channel responses,
        out-of-range camera/scene/truth attributes, frame rate inconsistent
        with the times (beyond FRAME_RATE_TOLERANCE), non-finite frames.
    """
    h5py = _h5py()
    p = os.fspath(path)
    if not os.path.exists(p):
        raise RecordingError(p, "file", "does not exist", "check the path")
    if os.path.isdir(p):
        raise RecordingError(p, "file", "is a directory, not a recording file")
    if not h5py.is_hdf5(p):
        raise RecordingError(
            p,
            "file",
            "is not an HDF5 file",
            "a qogi recording is HDF5 (see docs/recording.md); convert camera "
            "files with qogi.io (read_flir, read_numpy, read_tiff)",
        )
    try:
        f = h5py.File(p, "r")
    except OSError as e:
        raise RecordingError(
            p,
            "file",
            f"is not a readable HDF5 file ({e})",
            "the file is damaged or truncated; copy or export it again",
        ) from e
    try:
        rec = _read(f, p, nonfinite)
        if check_frames:
            rec._scan_frames()
    except BaseException as e:
        f.close()
        if isinstance(e, Exception) and not isinstance(e, RecordingError):
            raise _damaged(p, e) from e
        raise
    return rec


def _damaged(p: str, e: Exception) -> RecordingError:
    """What a failure of HDF5 or numpy while reading an untrusted file becomes
    (h5py raises OSError, KeyError, TypeError, ... on damaged structures)."""
    return RecordingError(
        p,
        "file",
        f"cannot be read ({type(e).__name__}: {e})",
        "the file is damaged or not written by a recording writer; export it again",
    )


#: Largest frame (C x H x W values of float32) a recording may declare [bytes]:
#: frames are read whole, so a forged shape must not reach an allocation.
MAX_FRAME_BYTES = 1 << 31
#: The most a stored /frames can be compressed (deflate's limit is ~1032:1,
#: lzf's far lower); a file declaring more data than this times what it stores
#: is truncated, sparse or forged.
_MAX_COMPRESSION = 2000


def _check_declared_size(p: str, ds) -> None:
    """Refuses /frames whose declared shape cannot be real before anything is
    read: one frame larger than :data:`MAX_FRAME_BYTES`, or far more data
    declared than the file stores."""
    t, c, h, w = (int(v) for v in ds.shape)
    frame_bytes = c * h * w * 4
    if min(t, c, h, w) < 1:
        raise RecordingError(
            p,
            "/frames",
            f"shape {ds.shape} has an empty axis",
            "write at least one frame of at least one pixel",
        )
    if frame_bytes > MAX_FRAME_BYTES:
        raise RecordingError(
            p,
            "/frames",
            f"shape {ds.shape} declares {frame_bytes / 2**30:.3g} GiB per frame "
            f"(at most {MAX_FRAME_BYTES / 2**30:g} GiB)",
            "the file is damaged or forged; frames must be (T, C, H, W) with "
            "the camera's real size",
        )
    declared = t * frame_bytes
    try:
        stored = int(ds.id.get_storage_size())
    except Exception:  # external or virtual storage: cannot tell  # noqa: BLE001
        return
    if declared > (64 << 20) and declared > _MAX_COMPRESSION * max(stored, 1):
        raise RecordingError(
            p,
            "/frames",
            f"shape {ds.shape} declares {declared / 2**30:.3g} GiB but the file "
            f"stores {stored / 2**20:.3g} MiB of frames",
            "the file is truncated or its frames were never written; re-export the recording",
        )


def _read(f, p: str, nonfinite: str) -> Recording:
    h5py = _h5py()
    _check_variable_length(f, p)
    fmt = _attr(f, "format", p, "/", fix=f'set the root attribute format="{FORMAT}"')
    if fmt != FORMAT:
        raise RecordingError(
            p,
            "/ attr format",
            f"is {fmt!r}, not {FORMAT!r}",
            "this is not a qogi recording; convert it with qogi.io or qogi.write_recording",
        )
    ver = _attr(f, "version", p, "/", fix=f"set the root attribute version={VERSION}")
    if not isinstance(ver, (int, np.integer)) or int(ver) != VERSION:
        raise RecordingError(
            p,
            "/ attr version",
            f"version {ver!r} is not supported (this qogi reads version {VERSION})",
            "write the file with a matching qogi version",
        )

    if "frames" not in f or not isinstance(f["frames"], h5py.Dataset):
        raise RecordingError(
            p, "/frames", "missing", "write the frames as a float32 dataset /frames (T, C, H, W)"
        )
    ds = f["frames"]
    if ds.ndim != 4:
        raise RecordingError(
            p,
            "/frames",
            f"expected 4 dimensions (T, C, H, W); got shape {ds.shape}",
            "store one channel axis even for a single channel: shape (T, 1, H, W)",
        )
    if not np.issubdtype(ds.dtype, np.floating):
        raise RecordingError(
            p,
            "/frames",
            f"dtype {ds.dtype} is not floating point (expected float32)",
            "store band radiance or radiometric temperature as float32; "
            "raw camera counts must be calibrated first (e.g. qogi.io.read_flir)",
        )
    quantity = _attr(
        ds,
        "quantity",
        p,
        "/frames",
        fix=f"set /frames attr quantity to one of {sorted(QUANTITIES)}",
    )
    if quantity not in QUANTITIES:
        raise RecordingError(
            p,
            "/frames attr quantity",
            f"unknown quantity {quantity!r}",
            f"use one of {sorted(QUANTITIES)} (band radiance in W/(m2 sr) "
            "or radiometric temperature in K)",
        )
    t_frames = ds.shape[0]
    _check_declared_size(p, ds)

    if "time_s" not in f:
        raise RecordingError(
            p, "/time_s", "missing", "write a float64 dataset /time_s with one time [s] per frame"
        )
    tds = f["time_s"]
    if not isinstance(tds, h5py.Dataset) or tds.shape != (t_frames,):
        raise RecordingError(
            p,
            "/time_s",
            f"expected shape ({t_frames},) to match the {t_frames} frames; "
            f"got {getattr(tds, 'shape', None)}",
            "write one time [s] per frame",
        )
    try:
        time_s = np.asarray(tds[()], dtype=np.float64)
    except (TypeError, ValueError):
        raise RecordingError(
            p, "/time_s", f"dtype {tds.dtype} is not numeric", "store the times as float64 seconds"
        ) from None
    _validate_time(p, time_s, t_frames)

    if "camera" not in f:
        raise RecordingError(
            p,
            "/camera",
            "missing",
            "write a group /camera with attrs name, ifov_rad, frame_rate_hz "
            "and the channel responses in /camera/channels/<k>",
        )
    cam = f["camera"]
    name = _attr(cam, "name", p, "/camera")
    ifov = _attr(
        cam,
        "ifov_rad",
        p,
        "/camera",
        fix="add /camera attr ifov_rad (angular size of one pixel, rad)",
    )
    rate = _attr(cam, "frame_rate_hz", p, "/camera", fix="add /camera attr frame_rate_hz (Hz)")
    netd = _attr(cam, "netd_K", p, "/camera", required=False)
    channels = _read_channels(cam, p, ds.shape[1])
    camera = Camera(str(name), ifov, channels, rate, netd)

    if "scene" not in f:
        raise RecordingError(
            p,
            "/scene",
            "missing",
            "write a group /scene with attrs distance_m, ambient_temperature_K, pressure_Pa",
        )
    sc = f["scene"]
    scene = Scene(
        distance_m=_attr(
            sc,
            "distance_m",
            p,
            "/scene",
            fix="add /scene attr distance_m (camera-to-plume distance, m)",
        ),
        ambient_temperature_K=_attr(
            sc,
            "ambient_temperature_K",
            p,
            "/scene",
            fix="add /scene attr ambient_temperature_K (K)",
        ),
        pressure_Pa=_attr(
            sc, "pressure_Pa", p, "/scene", fix="add /scene attr pressure_Pa (ambient pressure, Pa)"
        ),
        wind_speed_m_s=_attr(sc, "wind_speed_m_s", p, "/scene", required=False),
        gas_temperature_K=_attr(sc, "gas_temperature_K", p, "/scene", required=False),
        background_temperature_K=_attr(sc, "background_temperature_K", p, "/scene", required=False),
        species=_species(_attr(sc, "species", p, "/scene", required=False)),
    )

    truth = None
    if "truth" in f:
        g = f["truth"]
        rates, extra = {}, {}
        for k in g.attrs:
            v = _attr(g, k, p, "/truth")
            if k.startswith("emission_rate_kg_s_"):
                rates[k[len("emission_rate_kg_s_") :]] = v
            else:
                extra[k] = v
        datasets = {k: g[k] for k in g if isinstance(g[k], h5py.Dataset)}
        for k, d in datasets.items():  # read lazily; only small ones are read whole
            if k.startswith("plane_"):
                datasets[k] = _small(d, p, f"/truth/{k}")
        truth = Truth(rates, datasets, extra)

    rec = Recording(
        source=ds,
        time_s=time_s,
        quantity=quantity,
        camera=camera,
        scene=scene,
        truth=truth,
        path=p,
        nonfinite=nonfinite,
        h5file=f,
        attrs={k: _attr(f, k, p, "/") for k in f.attrs},
    )
    rec._validate_metadata()
    return rec


#: Wavenumbers a channel's response may be given at [cm-1]: 0.5-100 um, far
#: wider than any thermal camera (a forged 4.7e99 cm-1 broke the band tables).
_WAVENUMBER_RANGE_CM1 = (100.0, 20000.0)


def _read_channels(cam, p: str, n_channels: int) -> List[SpectralResponse]:
    h5py = _h5py()
    if "channels" not in cam or not isinstance(cam["channels"], h5py.Group):
        raise RecordingError(
            p,
            "/camera/channels",
            "missing (no spectral response)",
            "write one group /camera/channels/<k> per frame channel with "
            "datasets wavenumber_cm1 and response; the band radiance and "
            "radiometric temperature depend on it",
        )
    g = cam["channels"]
    keys = sorted(g.keys(), key=lambda k: (not k.isdigit(), int(k) if k.isdigit() else 0, k))
    expected = [str(k) for k in range(n_channels)]
    if keys != expected:
        raise RecordingError(
            p,
            "/camera/channels",
            f"members {keys} do not match the {n_channels} frame channels (expected {expected})",
            "name the channel groups 0 .. C-1 in frame channel order",
        )
    out = []
    for k in expected:
        loc = f"/camera/channels/{k}"
        ch = g[k]
        for d in ("wavenumber_cm1", "response"):
            if d not in ch:
                raise RecordingError(
                    p,
                    f"{loc}/{d}",
                    "missing",
                    "write the channel response as datasets wavenumber_cm1 "
                    "[cm-1] and response [dimensionless]",
                )
        nu = np.asarray(
            _small(ch["wavenumber_cm1"], p, f"{ch.name}/wavenumber_cm1"), dtype=np.float64
        )
        r = np.asarray(_small(ch["response"], p, f"{ch.name}/response"), dtype=np.float64)
        name = _attr(ch, "name", p, loc, required=False)
        lo_nu, hi_nu = _WAVENUMBER_RANGE_CM1
        if nu.size and not np.all((nu >= lo_nu) & (nu <= hi_nu)):
            bad = nu[~((nu >= lo_nu) & (nu <= hi_nu))][0]
            raise RecordingError(
                p,
                f"{loc}/wavenumber_cm1",
                f"{bad:g} cm-1 is outside the thermal infrared [{lo_nu:g}, {hi_nu:g}] cm-1",
                "store the response over wavenumbers in cm-1 (1 um = 10000 cm-1)",
            )
        try:
            out.append(
                SpectralResponse(np.ravel(nu), np.ravel(r), "" if name is None else str(name))
            )
        except (ValueError, TypeError) as e:
            raise RecordingError(
                p,
                loc,
                f"invalid spectral response: {e}",
                "wavenumber_cm1 must be strictly increasing, finite, >= 0 "
                "(at least 2 samples); response finite, >= 0, not all zero, "
                "same length",
            ) from None
    return out


def _write_metadata(f, quantity: str, camera: Camera, scene: Scene, truth: Optional[Truth]) -> None:
    set_attr(f, "format", FORMAT)
    f.attrs["version"] = np.int64(VERSION)
    cam = f.require_group("camera")
    set_attr(cam, "name", camera.name)
    cam.attrs["ifov_rad"] = float(camera.ifov_rad)
    if camera.frame_rate_hz is not None:
        cam.attrs["frame_rate_hz"] = float(camera.frame_rate_hz)
    if camera.netd_K is not None:
        cam.attrs["netd_K"] = float(camera.netd_K)
    chg = cam.require_group("channels")
    for k, ch in enumerate(camera.channels):
        g = chg.require_group(str(k))
        g.create_dataset("wavenumber_cm1", data=np.asarray(ch.nu_cm1, dtype=np.float64))
        g.create_dataset("response", data=np.asarray(ch.response, dtype=np.float64))
        set_attr(g, "name", ch.name)
    sc = f.require_group("scene")
    for name in (
        "distance_m",
        "ambient_temperature_K",
        "pressure_Pa",
        "wind_speed_m_s",
        "gas_temperature_K",
        "background_temperature_K",
    ):
        v = getattr(scene, name)
        if v is not None:
            sc.attrs[name] = float(v)
    if scene.species:
        set_attr(sc, "species", list(scene.species))
    if truth is not None:
        _write_truth(f, truth)


def _write_truth(f, truth: Truth) -> None:
    g = f.require_group("truth")
    for sp, rate in truth.emission_rate_kg_s.items():
        g.attrs[f"emission_rate_kg_s_{sp}"] = float(rate)
    for k, v in truth.attrs.items():
        set_attr(g, k, v)
    for k, v in truth.datasets.items():
        if k in g:
            del g[k]
        g.create_dataset(k, data=np.asarray(v))


def _compression_args(compression: Optional[str], level: Optional[int]) -> dict:
    if compression is None:
        return {}
    if compression == "gzip":
        return {
            "compression": "gzip",
            "compression_opts": 4 if level is None else int(level),
            "shuffle": True,
        }
    if compression == "lzf":
        return {"compression": "lzf", "shuffle": True}
    raise ValueError(f"compression must be None, 'gzip' or 'lzf'; got {compression!r}")


def write_recording(
    path: Union[str, os.PathLike],
    recording: Recording,
    *,
    compression: Optional[str] = None,
    compression_level: Optional[int] = None,
    overwrite: bool = True,
    batch_frames: Optional[int] = None,
    attrs: Optional[Dict[str, object]] = None,
    progress=None,
) -> None:
    """Write ``recording`` to an HDF5 file following the recording contract.

    Frames are chunked one frame per chunk (fast per-frame reads) and copied
    in batches, so a lazily opened recording is never loaded whole.

    Parameters
    ----------
    path : str or path
    recording : Recording
    compression : {None, "gzip", "lzf"}
        Optional lossless compression of /frames (with byte shuffling).
        gzip is smaller, lzf faster.
    compression_level : int, optional
        gzip level 0-9 (default 4).
    overwrite : bool, default True
        Refuse to replace an existing file when False.
    batch_frames : int, optional
        Frames copied per batch (default: ~64 MB worth).
    attrs : dict, optional
        Root attributes to write besides the recording's own (e.g. a
        conversion's origins), text as fixed-length UTF-8 (:func:`set_attr`).
    progress : callable(fraction, message), optional
        Called after each batch of frames.
    """
    if not isinstance(recording, Recording):
        raise TypeError(f"recording must be a qogi.Recording; got {type(recording).__name__}")
    if (
        not recording.in_memory
        and os.path.exists(os.fspath(path))
        and os.path.samefile(os.fspath(path), recording.path)
    ):
        raise ValueError(
            f"{os.fspath(path)}: cannot overwrite the file this recording is "
            "being read from; save to another path (or load() it first)"
        )
    t, c, h, w = recording.shape
    with RecordingWriter(
        path,
        quantity=recording.quantity,
        camera=recording.camera,
        scene=recording.scene,
        frame_shape=(c, h, w),
        truth=recording.truth,
        compression=compression,
        compression_level=compression_level,
        overwrite=overwrite,
        expected_frames=t,
        allow_nonfinite=recording.nonfinite == "invalid",
    ) as wr:
        step = batch_frames or max(1, (64 << 20) // max(1, c * h * w * 4))
        for s in range(0, t, step):
            e = min(t, s + step)
            wr.append(recording.frames(s, e), recording.time_s[s:e])
            if progress is not None:
                progress(e / t, f"frame {e}/{t}")
        for k, v in {**recording.attrs, **(attrs or {})}.items():
            if k not in ("format", "version"):
                set_attr(wr._f, k, v)


class RecordingWriter:
    """Write a recording frame by frame (for generators and converters).

    Parameters
    ----------
    path : str or path
        File to create.
    quantity : {"radiance", "radiometric_temperature"}
    camera : Camera
        ``camera.frame_rate_hz=None`` takes the rate from the written times
        at :meth:`close`.
    scene : Scene
    frame_shape : (C, H, W)
    truth : Truth, optional
        Can also be set later with :meth:`set_truth`.
    compression : {None, "gzip", "lzf"}, compression_level : int
        See :func:`write_recording`.
    overwrite : bool, default True
    expected_frames : int, optional
        Pre-sizes /frames (it still grows if more are appended).
    allow_nonfinite : bool, default False
        Accept NaN/inf pixels (invalid pixels); otherwise they are an error.
    keep_partial : bool, default False
        What an error or interruption before :meth:`close` leaves behind. By
        default nothing: the file is written under a temporary name beside
        ``path`` and renamed onto it only when :meth:`close` succeeds, so an
        existing file at ``path`` stays untouched (qogi.files). With True the
        frames written so far replace ``path`` as a valid recording whose root
        attribute ``complete`` is False.

    Every call validates its input and the metadata is validated up front,
    so an error comes before work is lost (times and frames are appended
    together, so a kept partial file is valid).

    Examples
    --------
    >>> with RecordingWriter("out.h5", quantity="radiance", camera=cam, scene=scene,
    ...                      frame_shape=(1, 64, 64)) as w:  # doctest: +SKIP
    ...     for i, frame in enumerate(render()):
    ...         w.append(frame, i / 15.0)
    """

    def __init__(
        self,
        path: Union[str, os.PathLike],
        *,
        quantity: str,
        camera: Camera,
        scene: Scene,
        frame_shape: Sequence[int],
        truth: Optional[Truth] = None,
        compression: Optional[str] = None,
        compression_level: Optional[int] = None,
        overwrite: bool = True,
        expected_frames: Optional[int] = None,
        allow_nonfinite: bool = False,
        keep_partial: bool = False,
    ):
        h5py = _h5py()
        self.path = os.fspath(path)
        if quantity not in QUANTITIES:
            raise RecordingError(
                self.path,
                "/frames attr quantity",
                f"unknown quantity {quantity!r}",
                f"use one of {sorted(QUANTITIES)}",
            )
        shape = tuple(int(s) for s in frame_shape)
        if len(shape) != 3 or min(shape) < 1:
            raise RecordingError(
                self.path,
                "/frames",
                f"frame_shape must be (C, H, W) with positive sizes; got {tuple(frame_shape)}",
            )
        camera.validate(self.path)
        scene.validate(self.path)
        if truth is not None:
            truth.validate(self.path)
        _check_channels(camera.channels, self.path, shape[0])
        if not overwrite and os.path.exists(self.path):
            raise FileExistsError(f"{self.path} exists (pass overwrite=True to replace it)")
        self.quantity, self.camera, self.scene = quantity, camera, scene
        self.frame_shape = shape
        self.allow_nonfinite = allow_nonfinite
        self._n = 0
        self._last_t = -math.inf
        self.keep_partial = bool(keep_partial)
        from .files import atomic_path

        self._atomic = atomic_path(self.path)
        tmp = self._atomic.__enter__()
        try:
            self._sink = GuardedFile(tmp, "w")  # a full disk: an error here, not in HDF5
            self._f = h5py.File(self._sink, "w")
        except BaseException as e:
            if getattr(self, "_sink", None) is not None:
                self._sink.close()
            self._atomic.__exit__(type(e), e, e.__traceback__)
            raise
        try:
            _write_metadata(self._f, quantity, camera, scene, truth)
            self._f.attrs["complete"] = False  # set True by close()
            n0 = int(expected_frames or 0)
            self._frames = self._f.create_dataset(
                "frames",
                shape=(n0,) + shape,
                maxshape=(None,) + shape,
                dtype=np.float32,
                chunks=(1,) + shape,
                **_compression_args(compression, compression_level),
            )
            set_attr(self._frames, "quantity", quantity)
            set_attr(self._frames, "unit", QUANTITIES[quantity])
            self._time = self._f.create_dataset(
                "time_s", shape=(n0,), maxshape=(None,), dtype=np.float64, chunks=(4096,)
            )
            set_attr(self._time, "unit", "s")
            self._sink.check()
        except BaseException as e:
            f, self._f = self._f, None
            f.close()
            self._sink.close()
            self._atomic.__exit__(type(e), e, e.__traceback__)
            raise

    @property
    def n_frames(self) -> int:
        return self._n

    @property
    def truth_group(self):
        """The open file's /truth group (h5py), for large truth datasets
        written frame by frame before :meth:`close`."""
        if self._f is None:
            raise ValueError(f"{self.path}: the writer is closed")
        return self._f.require_group("truth")

    def append(self, frames, time_s) -> None:
        """Append one frame (C, H, W) with its time [s], or a block (n, C, H, W)
        with n times. Times must keep increasing."""
        if self._f is None:
            raise ValueError(f"{self.path}: the writer is closed")
        a = np.asarray(frames, dtype=np.float32)
        if a.shape == self.frame_shape:
            a = a[None]
        if a.ndim != 4 or a.shape[1:] != self.frame_shape:
            raise RecordingError(
                self.path,
                "/frames",
                f"appended frames have shape {np.shape(frames)}; expected "
                f"{self.frame_shape} or (n,) + {self.frame_shape}",
            )
        t = np.atleast_1d(np.asarray(time_s, dtype=np.float64))
        if t.shape != (a.shape[0],):
            raise RecordingError(
                self.path, "/time_s", f"{t.size} times for {a.shape[0]} appended frames"
            )
        if not np.all(np.isfinite(t)) or np.any(np.diff(np.concatenate([[self._last_t], t])) <= 0):
            raise RecordingError(
                self.path,
                "/time_s",
                f"appended times {t.tolist()[:5]} are not finite and strictly "
                f"after the last written time {self._last_t!r}",
                "append frames in time order",
            )
        if not self.allow_nonfinite:
            bad = ~np.isfinite(a)
            if bad.any():
                loc = _first_nonfinite(a)
                raise RecordingError(
                    self.path,
                    "/frames",
                    f"{int(bad.sum())} non-finite values in the appended "
                    f"frames (first at frame {self._n + loc[0]}, c={loc[1]}, "
                    f"y={loc[2]}, x={loc[3]})",
                    "pass allow_nonfinite=True to store invalid pixels",
                )
        n0, n1 = self._n, self._n + a.shape[0]
        if n1 > self._frames.shape[0]:
            self._frames.resize(n1, axis=0)
            self._time.resize(n1, axis=0)
        self._frames[n0:n1] = a
        self._time[n0:n1] = t
        self._sink.check()  # a full disk stops the writer now, not at close()
        self._n = n1
        self._last_t = float(t[-1])

    def set_truth(self, truth: Truth) -> None:
        """Write (or replace) the /truth group."""
        truth.validate(self.path)
        _write_truth(self._f, truth)

    def close(self) -> None:
        """Finish the file: trim to the frames written, set the frame rate,
        check it against the times, and rename it onto ``path``. Raises
        RecordingError if no frame was written or the rate disagrees with the
        times (then ``path`` is left as it was, unless ``keep_partial``)."""
        if self._f is None:
            return
        try:
            if self._frames.shape[0] != self._n:
                self._frames.resize(self._n, axis=0)
                self._time.resize(self._n, axis=0)
            if self._n == 0:
                raise RecordingError(self.path, "/frames", "no frame was written")
            t = self._time[()]
            rate = self.camera.frame_rate_hz
            if rate is None:
                if self._n < 2:
                    raise RecordingError(
                        self.path,
                        "/camera attr frame_rate_hz",
                        "cannot be inferred from a single frame",
                        "set camera.frame_rate_hz",
                    )
                rate = 1.0 / typical_interval(t)
                self._f["camera"].attrs["frame_rate_hz"] = rate
            _check_frame_rate(self.path, t, rate)
            self._f.attrs["complete"] = True
            self._f.close()  # HDF5's last writes, through the guarded file
            self._sink.check()
        except BaseException as e:
            self._abandon(e)
            raise
        self._f = None
        self._sink.close()
        self._atomic.__exit__(None, None, None)

    def _abandon(self, exc: BaseException) -> None:
        """After an error: drop the temporary file, or (keep_partial) rename
        the frames written so far, marked incomplete, onto ``path``."""
        if self._f is None:
            return
        keep = False
        try:
            if self.keep_partial and self._n > 0 and self._sink.error is None and self._f.id:
                if self._frames.shape[0] != self._n:
                    self._frames.resize(self._n, axis=0)
                    self._time.resize(self._n, axis=0)
                if self.camera.frame_rate_hz is None and self._n >= 2:
                    t = self._time[()]
                    self._f["camera"].attrs["frame_rate_hz"] = 1.0 / typical_interval(t)
                self._f.attrs["complete"] = False
                keep = True
        finally:
            f, self._f = self._f, None
            try:
                if f.id:  # open (close() may have closed it before its check failed)
                    f.close()  # cannot fail on a full disk: the guarded file drops the writes
            finally:
                self._sink.close()
            if keep and self._sink.error is None:
                self._atomic.__exit__(None, None, None)
            else:
                err = exc if self._sink.error is None or is_no_space(exc) else self._sink.error
                self._atomic.__exit__(type(err), err, err.__traceback__)

    def __enter__(self) -> RecordingWriter:
        return self

    def __exit__(self, exc_type, exc, tb) -> None:
        if exc_type is None:
            self.close()
        else:
            self._abandon(exc)

    def __del__(self) -> None:  # never finished: no temporary left behind
        if getattr(self, "_f", None) is not None:
            try:
                self._abandon(RuntimeError("RecordingWriter dropped without close()"))
            except Exception:  # noqa: BLE001 (never raise from __del__)
                pass
