"""The qogi recording file (HDF5, docs/recording.md) read: :func:`open_recording`
checks the whole contract before it returns a lazily read :class:`qogi.Recording`.
"""

from __future__ import annotations

import os
import re
from typing import List, Tuple, Union

import numpy as np

from ..contract import FORMAT, QUANTITIES, VERSION, RecordingError, damaged, validate_time
from ..hdf5_files import _attr, _check_variable_length, _h5py, _small
from ..physics.camera import Camera
from ..physics.optics import SpectralResponse
from .recording import Recording, Scene, Truth


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
            raise damaged(p, e) from e
        raise
    return rec


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
    validate_time(p, time_s, t_frames)

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
