"""One entry point for every supported file: :func:`open_recording`.

qogi HDF5 recordings, FLIR .seq/.csq/.fff/radiometric .jpg and Telops .hcc
all open as the same lazy :class:`qogi.Recording` (frames read and converted
in blocks when asked for, never all at once).

Scene facts are never invented. What the file holds is used and its origin
recorded (``rec.scene_origin``: name -> where the value came from); what it
does not hold and the rate depends on must be given, or
:class:`qogi.errors.UsageError` names it and says why:

============================  =================  =============================
fact                          FLIR               Telops .hcc
============================  =================  =============================
camera (spectral response)    must be given      must be given
distance                      file (object       must be given
                              distance)
ambient temperature           file (atmospheric  must be given
                              temperature)
pressure                      standard 101325    standard 101325 Pa, flagged
                              Pa, flagged
IFOV                          file (FOV/width)   camera preset (or given)
frame times                   file (per frame)   file (per frame)
============================  =================  =============================

Values taken from the file that are known factory defaults of the camera
(FLIR's 1.0 m object distance and 20 C atmosphere) and the assumed pressure
are flagged in ``rec.warnings`` (:class:`qogi.diagnostics.Diagnostics`),
which :func:`qogi.quantify` copies into ``Result.warnings``.
"""

from __future__ import annotations

import abc
import dataclasses
import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

from ..contract import RecordingError, typical_interval
from ..diagnostics import Diagnostics
from ..errors import DataError, UsageError
from ..physics.camera import Camera
from ..physics.optics import SpectralResponse, channel_problem
from ..physics.presets import camera_preset, camera_preset_names
from .flir import FlirFile, flir_apparent_temperature, flir_temperature
from .hdf5 import open_recording as _open_hdf5
from .recording import Recording, Scene, _half_max_band
from .telops import CALIBRATION_MODES, HccFile, wheel_turns

__all__ = [
    "open_recording",
    "file_kind",
    "resolve_camera",
    "scene_needs",
    "STANDARD_PRESSURE_PA",
    "FLIR_DEFAULTS",
    "CAMERA_EXTENSIONS",
]

#: Pressure used when none is given (a file never holds it) [Pa]; flagged.
STANDARD_PRESSURE_PA = 101325.0
#: FLIR's factory defaults of the object parameters: a value equal to one of
#: these was most likely never set by the operator.
FLIR_DEFAULTS = {"distance_m": 1.0, "ambient_temperature_K": 293.15}
#: Relative distance between a channel's centroid and a FLIR calibration's
#: effective wavenumber B / c2 beyond which they belong to different bands.
BAND_TOLERANCE = 0.35


@dataclasses.dataclass(frozen=True)
class FileFormat:
    """One file format qogi reads, as the registry :data:`FORMATS` knows it.

    ``magic``: the first bytes that identify it (any of them); ``extensions``:
    the names it goes by, used only when a file is too short to show its first
    bytes; ``camera_file``: a camera's own file (FLIR, Telops), which does not
    hold the scene facts and spectral responses a recording needs.
    """

    kind: str
    description: str
    magic: Tuple[bytes, ...]
    extensions: Tuple[str, ...]
    camera_file: bool = False

    def recognises(self, head: bytes) -> bool:
        """Whether a file starting with ``head`` is of this format."""
        return any(head.startswith(m) for m in self.magic)


#: Every format qogi reads: the one registry behind :func:`file_kind`,
#: :func:`open_recording` and :func:`qogi.io.read_recording`. A file is
#: recognised by its first bytes, whatever its name.
FORMATS = (
    FileFormat("hdf5", "qogi recording (HDF5)", (b"\x89HDF\r\n\x1a\n",), (".h5", ".hdf5", ".hdf")),
    FileFormat(
        "flir",
        "FLIR radiometric file (.seq, .csq, .fff, radiometric .jpg)",
        (b"FFF\x00", b"AFF\x00", b"\xff\xd8"),
        (".seq", ".csq", ".fff", ".jpg", ".jpeg"),
        camera_file=True,
    ),
    FileFormat("telops", "Telops .hcc", (b"TC",), (".hcc",), camera_file=True),
    FileFormat(
        "numpy", "numpy array (.npy, .npz)", (b"\x93NUMPY", b"PK\x03\x04"), (".npy", ".npz")
    ),
    FileFormat("tiff", "multi-page TIFF", (b"II*\x00", b"MM\x00*"), (".tif", ".tiff")),
)


def file_format(kind: str) -> FileFormat:
    """The registry's entry for ``kind``."""
    for f in FORMATS:
        if f.kind == kind:
            return f
    raise KeyError(kind)


#: Extensions of the camera files :func:`open_recording` reads.
CAMERA_EXTENSIONS = tuple(e for f in FORMATS if f.camera_file for e in f.extensions)


def file_kind(path: Union[str, os.PathLike]) -> str:
    """The :data:`FORMATS` kind of a file (``"hdf5"``, ``"flir"``,
    ``"telops"``, ``"numpy"``, ``"tiff"``) from its first bytes (from its
    extension when they say nothing), or ``"unknown"``."""
    p = os.fspath(path)
    try:
        with open(p, "rb") as fh:
            head = fh.read(8)
    except OSError:
        head = b""
    for f in FORMATS:
        if f.recognises(head):
            return f.kind
    # Not recognised (too short, unreadable, or damaged): by its name, so that
    # the reader of that format says what is wrong with it.
    ext = os.path.splitext(p)[1].lower()
    for f in FORMATS:
        if ext in f.extensions:
            return f.kind
    return "unknown"


def resolve_camera(camera, *, ifov_rad: Optional[float] = None) -> Camera:
    """A :class:`qogi.Camera` from a preset name (``gf320``, ``fast-m150``), a
    CSV spectral response (one channel), a SpectralResponse or a Camera."""

    if isinstance(camera, Camera):
        return camera
    if isinstance(camera, SpectralResponse):
        return Camera(camera.name or "custom", ifov_rad if ifov_rad is not None else 0.0, [camera])
    if isinstance(camera, (str, os.PathLike)):
        s = os.fspath(camera)
        if s in camera_preset_names():
            return camera_preset(s)
        if os.path.isfile(s):
            try:
                ch = SpectralResponse.from_csv(s)
            except ValueError as e:
                raise UsageError(f"--camera {s}: not a spectral-response CSV ({e})") from None
            return Camera(os.path.basename(s), ifov_rad if ifov_rad is not None else 0.0, [ch])
        raise UsageError(
            f"--camera {s!r} is neither a camera preset "
            f"({', '.join(camera_preset_names())}) nor a response CSV file "
            "(two columns: wavenumber_cm1 or wavelength_um, response)"
        )
    raise UsageError(
        f"camera must be a preset name, a CSV path, a qogi.SpectralResponse or a "
        f"qogi.Camera; got {type(camera).__name__}"
    )


def _missing(path: str, what: str, why: str, flag: str) -> UsageError:
    e = UsageError(
        f"{path}: {what} is needed and the file does not hold it: {why}. Give it with {flag}"
    )
    e.missing = what  # type: ignore[attr-defined]
    return e


def _ifov(p, given, in_file, cam, origins: dict, why_missing: str) -> float:
    """A camera file's IFOV [rad]: the one given, else the file's (its field
    of view / width; None where it holds none), else the camera preset's;
    its origin goes into ``origins``. Without any, the usage error naming
    ``ifov_rad`` (``why_missing``: why the file does not hold it)."""
    if given is not None:
        ifov, origins["ifov_rad"] = float(given), "given"
    elif in_file is not None:
        ifov, origins["ifov_rad"] = in_file, "file (field of view / width)"
    elif cam.ifov_rad > 0:
        ifov, origins["ifov_rad"] = cam.ifov_rad, "camera preset"
    else:
        raise _missing(p, "the IFOV", why_missing, "ifov_rad=... (angular size of one pixel, rad)")
    return ifov


def _no_camera(path: str, kind: str) -> UsageError:

    return _missing(
        path,
        "the camera (spectral response)",
        f"a {kind} file holds calibrated frames but not the camera's spectral response, which "
        "the gas absorption in each pixel's band is computed with",
        f"--camera {'|'.join(camera_preset_names())}|response.csv (Python: camera=...)",
    )


def _band_um(ch: SpectralResponse) -> str:

    lo, hi = _half_max_band(ch)
    return f"{1e4 / hi:.2f}-{1e4 / lo:.2f} um"


# --------------------------------------------------------------------------- lazy sources


class _FileFrames(abc.ABC):
    """A lazy frame source over an open camera file, which ``close`` closes."""

    @abc.abstractmethod
    def close(self) -> None:
        """Closes the camera file (each source its own)."""

    def __del__(self) -> None:  # a recording dropped without close() releases its file
        try:
            self.close()
        except Exception:  # noqa: BLE001 (never raise from __del__)
            pass


class _FlirFrames(_FileFrames):
    """Apparent (or object) radiometric temperature of a FLIR file's frames,
    (T, 1, H, W) float32, decoded per block with each frame's own Planck
    constants."""

    def __init__(self, flir, n: int, h: int, w: int, object_parameters: bool):
        self.flir, self.object_parameters = flir, object_parameters
        self.shape = (n, 1, h, w)
        self.dtype = np.dtype(np.float32)

    def __getitem__(self, sl) -> np.ndarray:

        idx = range(self.shape[0])[sl]
        out = np.empty((len(idx),) + self.shape[1:], np.float32)
        for k, i in enumerate(idx):
            fr = self.flir.frame(i)
            if fr.raw.shape != self.shape[2:]:
                raise DataError(
                    f"{self.flir.path}: frame {i} is {fr.raw.shape[1]}x"
                    f"{fr.raw.shape[0]}, frame 0 {self.shape[3]}x{self.shape[2]}"
                )
            t = (
                flir_temperature(fr.raw, fr.metadata)
                if self.object_parameters
                else flir_apparent_temperature(fr.raw, fr.metadata)
            )
            out[k, 0] = t
        return out

    def close(self) -> None:
        self.flir.close()


class _HccFrames(_FileFrames):
    """Calibrated values of a Telops file's frames grouped per wheel turn,
    (T, C, H, W) float32, each frame with its own scaling; ``factor``
    converts the stored unit to the recording's quantity."""

    def __init__(self, hcc, turns: np.ndarray, factor: float):
        self.hcc, self.turns, self.factor = hcc, turns, factor
        self.shape = (turns.shape[0], turns.shape[1], hcc.height, hcc.width)
        self.dtype = np.dtype(np.float32)

    def __getitem__(self, sl) -> np.ndarray:
        rows = self.turns[sl]
        v = self.hcc.values(rows.ravel()) * self.factor
        return v.reshape(rows.shape + (self.hcc.height, self.hcc.width)).astype(np.float32)

    def close(self) -> None:
        self.hcc.close()


# --------------------------------------------------------------------------- the opener


def open_recording(
    path: Union[str, os.PathLike],
    camera=None,
    distance_m: Optional[float] = None,
    ambient_temperature_K: Optional[float] = None,
    pressure_Pa: Optional[float] = None,
    *,
    ifov_rad: Optional[float] = None,
    nonfinite: str = "error",
    check_frames: Optional[bool] = None,
    object_parameters: bool = False,
    species=(),
) -> Recording:
    """Open a qogi HDF5 recording or a camera file as a lazy :class:`Recording`.

    Parameters
    ----------
    path : str or path
        .h5 (qogi recording), FLIR .seq/.csq/.fff/radiometric .jpg, Telops .hcc
        (recognised by their first bytes).
    camera : str, path, SpectralResponse or Camera, optional
        Required for camera files (they do not hold the spectral response):
        a preset (``"gf320"``, ``"fast-m150"``) or a response CSV. Refused for
        HDF5 recordings, which carry their camera.
    distance_m : float, m, optional
        Camera-to-plume distance. Required for Telops files; FLIR files hold
        an object distance (used, flagged when it is FLIR's default 1 m).
        For an HDF5 recording it overrides the stored one.
    ambient_temperature_K : float, K, optional
        Required for Telops files; FLIR files hold the atmospheric
        temperature (used, flagged when it is FLIR's default 20 C).
    pressure_Pa : float, Pa, optional
        Default for camera files: 101325 Pa (flagged in ``rec.warnings``).
    ifov_rad : float, rad, optional
        One pixel's angular size; default the file's (FLIR: field of view /
        width) or the camera preset's.
    nonfinite, check_frames
        As :func:`qogi.io.hdf5.open_recording`. Camera files mark pixels
        outside the calibration (FLIR) or flagged bad (Telops) as invalid
        (NaN), and are not scanned on open unless ``check_frames=True``.
    object_parameters : bool
        FLIR: FLIR's emissivity-corrected object temperature instead of the
        apparent temperature (see :func:`qogi.io.read_flir_recording`).
    species : sequence of str
        Scene species (camera files do not hold them).

    Returns
    -------
    Recording
        Also ``rec.scene_origin`` (fact -> origin), ``rec.warnings``
        (Diagnostics) and, for a filter wheel, ``rec.channel_time_s`` (T, C).

    Raises
    ------
    qogi.errors.UsageError
        A missing scene fact or camera (naming which and why), a camera
        whose band does not match the file's calibration, an unsupported
        calibration mode.
    qogi.RecordingError / DataError
        A malformed file.
    """
    p = os.fspath(path)
    kind = file_kind(p) if os.path.isfile(p) else "hdf5"
    if kind == "hdf5":
        return _open_h5(
            p,
            camera,
            distance_m,
            ambient_temperature_K,
            pressure_Pa,
            nonfinite,
            True if check_frames is None else check_frames,
        )
    if kind == "flir":
        rec = _open_flir(
            p,
            camera,
            distance_m,
            ambient_temperature_K,
            pressure_Pa,
            ifov_rad,
            nonfinite,
            object_parameters,
            species,
        )
    elif kind == "telops":
        rec = _open_hcc(
            p, camera, distance_m, ambient_temperature_K, pressure_Pa, ifov_rad, nonfinite, species
        )
    elif kind in ("numpy", "tiff"):
        raise UsageError(
            f"{p}: a {file_format(kind).description} holds frames without a camera or "
            "scene; read it with qogi.io.read_recording (or read_numpy / read_tiff), "
            "giving them"
        )
    else:
        raise UsageError(
            f"{p}: unknown file type (not HDF5, FLIR FFF/JPEG or Telops .hcc by "
            "its first bytes); qogi opens .h5 recordings, FLIR .seq/.csq/.fff/"
            ".jpg and Telops .hcc (numpy/TIFF arrays: qogi.io.read_numpy/read_tiff)"
        )
    if check_frames:
        try:
            rec._scan_frames()
        except BaseException:
            rec.close()
            raise
    return rec


def _open_h5(p, camera, distance_m, ambient_K, pressure_Pa, nonfinite, check_frames):
    if camera is not None:
        raise UsageError(
            f"{p}: a qogi recording carries its own camera (spectral responses); "
            "--camera is for camera files (.seq, .csq, .jpg, .fff, .hcc)"
        )
    rec = _open_hdf5(p, nonfinite=nonfinite, check_frames=check_frames)
    origins = dict.fromkeys(("distance_m", "ambient_temperature_K", "pressure_Pa"), "file")
    given = {
        k: v
        for k, v in (
            ("distance_m", distance_m),
            ("ambient_temperature_K", ambient_K),
            ("pressure_Pa", pressure_Pa),
        )
        if v is not None
    }
    if given:
        try:
            changes: Dict[str, Any] = {k: float(v) for k, v in given.items()}
            scene = dataclasses.replace(rec.scene, **changes)
            scene.validate(p)
        except BaseException:
            rec.close()
            raise
        rec.scene = scene
        origins.update(dict.fromkeys(given, "given"))
    rec.scene_origin = origins  # type: ignore[attr-defined]
    rec.warnings = Diagnostics()  # type: ignore[attr-defined]
    return rec


def _camera_file_recording(
    p, source, times, quantity: str, camera: Camera, scene: Scene, nonfinite: str, attrs: dict
) -> Recording:
    """A recording of a camera file (FLIR, Telops): no truth, frames read from
    ``source`` (closed with the recording), ``nonfinite="error"`` (the
    default) taken as ``"invalid"`` as for every camera file; its metadata
    validated."""
    rec = Recording(
        source=source,
        time_s=np.asarray(times, np.float64),
        quantity=quantity,
        camera=camera,
        scene=scene,
        truth=None,
        path=p,
        nonfinite="invalid" if nonfinite == "error" else nonfinite,
        h5file=source,
        attrs=attrs,
    )
    rec._validate_metadata()
    return rec


def _scene(p, facts: dict, species) -> Scene:
    try:
        scene = Scene(
            distance_m=facts["distance_m"],
            ambient_temperature_K=facts["ambient_temperature_K"],
            pressure_Pa=facts["pressure_Pa"],
            species=tuple(species),
        )
        scene.validate(p)
    except RecordingError as e:
        raise UsageError(str(e)) from None
    return scene


def _pressure(p, pressure_Pa, origins, warns) -> float:
    if pressure_Pa is not None:
        origins["pressure_Pa"] = "given"
        return float(pressure_Pa)
    origins["pressure_Pa"] = "assumed (standard sea-level pressure)"
    warns.add(
        "scene-pressure-assumed",
        f"{os.path.basename(p)} does not record the ambient pressure; {STANDARD_PRESSURE_PA:g}"
        " Pa (sea level) is assumed (the gas lines' pressure broadening depends on it); give "
        "--pressure for a site at altitude",
        value_Pa=STANDARD_PRESSURE_PA,
    )
    return STANDARD_PRESSURE_PA


def _times(p, stamps: np.ndarray, nominal_hz: float, warns: Diagnostics):
    """Frame times [s] from the per-frame stamps (from the first frame), the
    frame rate, and how many frames are missing."""
    n = len(stamps)
    if n > 1 and np.all(np.diff(stamps) > 0):
        t = stamps - stamps[0]
        dt = typical_interval(t)
        gaps = np.diff(t) / dt
        missing = int(np.sum(np.maximum(np.rint(gaps) - 1, 0)))
        if missing:
            first = int(np.flatnonzero(gaps > 1.5)[0])
            warns.add(
                "frames-dropped",
                f"{os.path.basename(p)}: the frame time stamps show {missing} missing "
                f"frame(s) (the first gap after frame {first}, {t[first + 1] - t[first]:.4g} s "
                f"for a {dt:.4g} s interval); the pipeline uses the stamped times",
                missing=missing,
                first_gap_after_frame=first,
            )
        return t, 1.0 / dt
    if n == 1:
        if nominal_hz > 0:
            return np.zeros(1), float(nominal_hz)
        raise DataError(f"{p}: a single frame with no frame rate")
    if nominal_hz > 0:
        bad = int(np.flatnonzero(np.diff(stamps) <= 0)[0])
        warns.add(
            "frame-times-from-rate",
            f"{os.path.basename(p)}: the frame time stamps do not increase (frame {bad + 1} "
            f"at {stamps[bad + 1]!r} s after frame {bad} at {stamps[bad]!r} s); times are "
            f"frame index / the nominal {nominal_hz:g} Hz, so dropped frames cannot be seen",
        )
        return np.arange(n) / float(nominal_hz), float(nominal_hz)
    raise DataError(
        f"{p}: the frame time stamps do not increase and the file has no frame "
        "rate: frame times are unknown"
    )


def _open_flir(
    p, camera, distance_m, ambient_K, pressure_Pa, ifov_rad, nonfinite, object_parameters, species
) -> Recording:

    if camera is None:
        # A file that is not FLIR data says so before the camera is asked for
        # (a damaged file is a DataError whatever the arguments).
        with FlirFile(p) as probe:
            for i in range(len(probe)):
                probe.metadata(i)
        raise _no_camera(p, "FLIR")
    cam = resolve_camera(camera, ifov_rad=ifov_rad)
    if channel_problem(cam.channels, 1) is not None:
        raise UsageError(
            f"{p}: a FLIR file holds one channel; the camera {cam.name!r} has "
            f"{len(cam.channels)} (give a one-channel camera, e.g. gf320 or a "
            "response CSV)"
        )
    ch = cam.channels[0]
    f = FlirFile(p)
    try:
        metas = [f.metadata(i) for i in range(len(f))]
        m0 = metas[0]
        nu_eff = m0.effective_wavenumber_cm1
        if not (nu_eff > 0 and abs(ch.centroid_cm1 - nu_eff) <= BAND_TOLERANCE * nu_eff):
            file_band = (
                f"{1e4 / nu_eff:.1f} um ({nu_eff:.0f} cm-1, from its Planck B = "
                f"{m0.planck_b:g} K = c2 x wavenumber)"
                if nu_eff > 0
                else f"unknown (Planck B = {m0.planck_b:g} K)"
            )
            kind = (
                "a long-wave (LWIR) camera"
                if 0 < nu_eff < 1450
                else "a mid-wave (MWIR) camera"
                if nu_eff >= 1450
                else "an unknown band"
            )
            raise UsageError(
                f"{p}: the file's camera ({m0.camera_model or 'FLIR'}) is calibrated near "
                f"{file_band}: {kind}; the camera {cam.name!r} given sees "
                f"{_band_um(ch)} (centroid {1e4 / ch.centroid_cm1:.2f} um). Its frames cannot be "
                "read through that band: give the spectral response of the camera that recorded "
                "the file (--camera response.csv); a long-wave camera does not see methane's "
                "3.3 um band"
            )
        if len({(m.width, m.height) for m in metas}) != 1:
            raise DataError(
                f"{p}: frames have different sizes {sorted({(m.width, m.height) for m in metas})}"
            )
        warns, origins = Diagnostics(), {"camera": "given", "time_s": "file (frame time stamps)"}
        for msg in f.damaged:  # frames the reader had to leave out
            warns.add("frames-damaged", msg)
        times, rate = _times(p, np.array([m.timestamp_s for m in metas]), m0.frame_rate_hz, warns)
        if warns.has("frame-times-from-rate"):
            origins["time_s"] = "file (nominal frame rate)"
        facts = {}
        name = os.path.basename(p)
        for key, given, held, label, flag in (
            ("distance_m", distance_m, m0.object_distance_m, "object distance", "--distance"),
            (
                "ambient_temperature_K",
                ambient_K,
                m0.atmospheric_temperature_K,
                "atmospheric temperature",
                "--ambient-temperature",
            ),
        ):
            if given is not None:
                facts[key], origins[key] = float(given), "given"
                continue
            if not (np.isfinite(held) and held > 0):
                raise _missing(
                    p,
                    key.replace("_", " "),
                    f"the file's {label} is {held!r}, not a usable value",
                    flag,
                )
            facts[key], origins[key] = float(held), f"file (FLIR {label})"
            if abs(held - FLIR_DEFAULTS[key]) < 1e-4:
                unit = "m" if key == "distance_m" else "K"
                warns.add(
                    "scene-camera-default",
                    f"{name}: the {label} {held:g} {unit} is FLIR's factory default, "
                    f"probably never set for this scene; "
                    + (
                        "the rate scales with the distance: give --distance"
                        if key == "distance_m"
                        else "give --ambient-temperature"
                    ),
                    fact=key,
                    value=float(held),
                )
        facts["pressure_Pa"] = _pressure(p, pressure_Pa, origins, warns)
        in_file = m0.field_of_view_deg > 0 and m0.width > 0
        ifov = _ifov(
            p,
            ifov_rad,
            np.deg2rad(m0.field_of_view_deg) / m0.width if in_file else None,
            cam,
            origins,
            "the file has no field of view and the camera none",
        )
        camera_out = Camera(
            " ".join(s for s in (m0.camera_model, m0.lens_model) if s) or cam.name,
            float(ifov),
            [ch],
            float(rate),
            cam.netd_K,
        )
        scene = _scene(p, facts, species)
        source = _FlirFrames(f, len(metas), m0.height, m0.width, object_parameters)
        rec = _camera_file_recording(
            p,
            source,
            times,
            "radiometric_temperature",
            camera_out,
            scene,
            nonfinite,
            {
                "source": name,
                "source_format": f"FLIR {f.kind} ({m0.raw_format})",
                "start_time_posix_s": float(m0.timestamp_s),
                "camera_preset": cam.name,
                "flir_temperature": "object" if object_parameters else "apparent",
                "flir_planck_r1": m0.planck_r1,
                "flir_planck_r2": m0.planck_r2,
                "flir_planck_b": m0.planck_b,
                "flir_planck_f": m0.planck_f,
                "flir_planck_o": m0.planck_o,
            },
        )
    except BaseException:
        f.close()
        raise
    rec.scene_origin = origins  # type: ignore[attr-defined]
    rec.warnings = warns  # type: ignore[attr-defined]
    return rec


def _open_hcc(
    p, camera, distance_m, ambient_K, pressure_Pa, ifov_rad, nonfinite, species
) -> Recording:

    h = HccFile(p)
    try:
        fields = h.fields()
        modes = sorted(set(fields["CalibrationMode"].tolist()))
        if len(modes) != 1:
            raise DataError(
                f"{p}: the calibration mode changes within the file ({modes}); "
                "export it with one mode"
            )
        mode = modes[0]
        mname, quantity, _unit = CALIBRATION_MODES.get(mode, (f"mode {mode}", None, "?"))
        if quantity is None:  # the file's content, not an argument: bad data (exit 3)
            raise DataError(
                f"{p}: calibration mode {mname} ({mode}) holds uncalibrated detector counts; "
                "qogi needs radiometric data: export the sequence as RT (radiometric "
                "temperature) or IBR (in-band radiance) with Telops Reveal IR"
            )
        if camera is None:
            raise _no_camera(p, "Telops .hcc")
        cam = resolve_camera(camera, ifov_rad=ifov_rad)
        wheel = fields["FWMode"].any() and len(set(fields["FWPosition"].tolist())) > 1
        if wheel:
            order, turns, skipped = wheel_turns(fields["FWPosition"])
        else:
            order, turns, skipped = (
                [int(fields["FWPosition"][0])],
                np.arange(h.n_frames)[:, None],
                0,
            )
        positions = sorted(order)
        if channel_problem(cam.channels, len(positions)) is not None:
            raise UsageError(
                f"{p}: the file has {len(positions)} filter position(s) "
                f"({', '.join(map(str, positions))}) but the camera {cam.name!r} has "
                f"{len(cam.channels)} channel(s); give the camera whose channel k is filter "
                "position k (sorted), e.g. --camera fast-m150 for a four-filter wheel"
            )
        if turns.shape[0] == 0:
            raise DataError(
                f"{p}: no complete wheel turn (positions in file order: "
                f"{fields['FWPosition'][:12].tolist()} ...)"
            )
        warns = Diagnostics()
        name = os.path.basename(p)
        origins = {"camera": "given", "time_s": "file (POSIX time + sub-second ticks)"}
        if skipped:
            warns.add(
                "frames-dropped",
                f"{name}: {skipped} frame(s) left out because their wheel turn was "
                "incomplete (a dropped frame)",
                missing=int(skipped),
            )
        if h.trailing_bytes:  # a last frame cut off (a truncated copy or recording)
            warns.add(
                "frames-damaged",
                f"{name}: the {h.trailing_bytes} bytes after frame {h.n_frames - 1} are less "
                f"than a whole frame ({h.stride} bytes): a cut-off last frame was left out",
                trailing_bytes=int(h.trailing_bytes),
            )
        facts = {}
        for key, given, flag, why in (
            (
                "distance_m",
                distance_m,
                "--distance",
                "the column density per pixel and the pixel's size at the plume scale with it",
            ),
            (
                "ambient_temperature_K",
                ambient_K,
                "--ambient-temperature",
                "the gas temperature (assumed ambient) and the air between camera and plume "
                "depend on it",
            ),
        ):
            if given is None:
                raise _missing(
                    p,
                    key.replace("_", " ").replace(" K", "").replace(" m", ""),
                    f"a Telops .hcc file does not record it, and {why}",
                    flag,
                )
            facts[key], origins[key] = float(given), "given"
        facts["pressure_Pa"] = _pressure(p, pressure_Pa, origins, warns)
        ifov = _ifov(p, ifov_rad, None, cam, origins, "a Telops file does not record the lens")
        factor = 1.0
        if quantity == "irradiance":
            # An extended source filling the pixel: E = L x (pixel solid angle).
            factor, quantity = 1.0 / ifov**2, "radiance"
        ftimes = fields["time_s"]
        ch_times = ftimes[turns]  # (T, C) POSIX s
        turn_t = ch_times.mean(axis=1)
        t0 = float(turn_t[0])  # time zero: the first turn's mean
        times, rate = _times(
            p, turn_t, fields["AcquisitionFrameRate"][0] / 1000.0 / max(1, len(positions)), warns
        )
        camera_out = Camera(cam.name, float(ifov), list(cam.channels), float(rate), cam.netd_K)
        scene = _scene(p, facts, species)
        source = _HccFrames(h, turns, factor)
        offsets = (ch_times - ch_times.mean(axis=1, keepdims=True)).mean(axis=0)
        rec = _camera_file_recording(
            p,
            source,
            times,
            quantity,
            camera_out,
            scene,
            nonfinite,
            {
                "source": name,
                "source_format": f"Telops hcc v{h.version[0]}.{h.version[1]} ({mname})",
                "start_time_posix_s": t0,
                "camera_preset": cam.name,
                "telops_calibration_mode": mname,
                "telops_filter_positions": np.asarray(positions, np.int64),
                "channel_time_offset_s": offsets,
            },
        )
    except BaseException:
        h.close()
        raise
    rec.channel_time_s = ch_times - t0  # type: ignore[attr-defined]
    rec.scene_origin = origins  # type: ignore[attr-defined]
    rec.warnings = warns  # type: ignore[attr-defined]
    return rec


# --------------------------------------------------------------------------- what is needed


def scene_needs(path: Union[str, os.PathLike]) -> Dict[str, object]:
    """What a file holds and what opening it as a recording needs, without
    asking for anything: ``{"kind", "holds": {fact: value}, "needs": [fact,
    ...], "defaults": [fact, ...]}`` (defaults: values that are the camera's
    factory defaults). For ``qogi info`` and the viewer's form."""
    p = os.fspath(path)
    kind = file_kind(p)
    holds: Dict[str, object] = {}
    needs: List[str] = []
    defaults: List[str] = []
    if kind == "flir":
        with FlirFile(p) as f:
            m = f.metadata(0)
        flir: Dict[str, Optional[float]] = {
            "distance_m": m.object_distance_m,
            "ambient_temperature_K": m.atmospheric_temperature_K,
            "band_um": 1e4 / m.effective_wavenumber_cm1 if m.planck_b > 0 else None,
            "ifov_rad": np.deg2rad(m.field_of_view_deg) / m.width if m.width else None,
        }
        needs = ["camera"]
        holds = dict(flir)
        defaults = [
            k
            for k, v in FLIR_DEFAULTS.items()
            if (held := flir[k]) is not None and abs(held - v) < 1e-4
        ]
    elif kind == "telops":
        with HccFile(p) as h:
            fl = h.fields()
        pos = sorted(set(fl["FWPosition"].tolist())) if fl["FWMode"].any() else []
        holds = {
            "calibration_mode": CALIBRATION_MODES.get(int(fl["CalibrationMode"][0]), ("?",))[0],
            "filter_positions": pos,
            "frames": int(len(fl["FrameID"])),
        }
        needs = ["camera", "distance_m", "ambient_temperature_K"]
    elif kind == "hdf5":
        needs = []
    return {"kind": kind, "holds": holds, "needs": needs, "defaults": defaults}
