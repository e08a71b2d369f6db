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

import os
from dataclasses import dataclass, field
from typing import Any, Dict, Iterator, List, Optional, Tuple, Union

import numpy as np

from ..contract import (
    FORMAT,
    MEMORY,
    QUANTITIES,
    SCENE_OPTIONAL,
    SCENE_REQUIRED,
    SPECIES_RE,
    VERSION,
    RecordingError,
    check_frame_rate,
    check_range,
    damaged,
    first_nonfinite,
    frame_rate_from_times,
    validate_time,
)
from ..errors import DataError
from ..hdf5_files import set_attr
from ..physics.camera import Camera, check_channels
from ..physics.optics import SpectralResponse
from ..physics.radiometry import band_table
from .hdf5_writer import RecordingWriter


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

    def validate(self, path: str = MEMORY) -> None:
        """Raise :class:`RecordingError` unless every field is in range."""
        for name in SCENE_REQUIRED:
            check_range(f"scene.{name}", getattr(self, name), path, f"/scene attr {name}")
        for name in SCENE_OPTIONAL:
            v = getattr(self, name)
            if v is not None:
                check_range(f"scene.{name}", v, path, f"/scene attr {name}")
        for s in self.species:
            if not isinstance(s, str) or not SPECIES_RE.match(s):
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

    def validate(self, path: str = MEMORY) -> None:
        for sp, rate in self.emission_rate_kg_s.items():
            if not SPECIES_RE.match(str(sp)):
                raise RecordingError(
                    path,
                    f"/truth attr emission_rate_kg_s_{sp}",
                    f"species name {sp!r} is not a molecule name",
                )
            check_range(
                "truth.emission_rate_kg_s", rate, path, f"/truth attr emission_rate_kg_s_{sp}"
            )


# --------------------------------------------------------------------------- frames


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
                MEMORY,
                "frames",
                f"dtype {a.dtype} is not numeric",
                "pass band radiance or radiometric temperature as numbers",
            )
        a = np.ascontiguousarray(a, dtype=np.float32)
        if a.ndim != 4:
            raise RecordingError(
                MEMORY,
                "frames",
                f"expected shape (T, C, H, W) or (T, H, W); got {a.shape}",
                "stack frames as (time, channel, height, width)",
            )
        if time_s is None:
            if camera.frame_rate_hz is None:
                raise RecordingError(
                    MEMORY,
                    "time_s",
                    "neither time_s nor camera.frame_rate_hz was given",
                    "pass time_s (s) or set camera.frame_rate_hz",
                )
            check_range(
                "camera.frame_rate_hz", camera.frame_rate_hz, MEMORY, "camera.frame_rate_hz"
            )
            time_s = np.arange(a.shape[0], dtype=np.float64) / float(camera.frame_rate_hz)
        t = np.asarray(time_s, dtype=np.float64)
        cam = Camera(
            camera.name, camera.ifov_rad, list(camera.channels), camera.frame_rate_hz, camera.netd_K
        )
        validate_time(MEMORY, t, a.shape[0], "time_s")
        if cam.frame_rate_hz is None:
            cam.frame_rate_hz = frame_rate_from_times(t)
        rec = cls(
            source=a,
            time_s=t,
            quantity=quantity,
            camera=cam,
            scene=scene,
            truth=truth,
            path=MEMORY,
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
            if self.path == MEMORY or isinstance(e, DataError):
                raise
            raise damaged(self.path, e) from e
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
        first = first_nonfinite(block)
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
        check_channels(self.camera.channels, path, c)
        check_frame_rate(path, self.time_s, self.camera.frame_rate_hz)

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
                    loc = first_nonfinite(block)
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
            "scene": {k: getattr(self.scene, k) for k in SCENE_REQUIRED + SCENE_OPTIONAL},
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
