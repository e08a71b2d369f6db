"""Plain arrays as recordings: numpy .npy/.npz and multi-page TIFF stacks.

These files hold only pixels, so the camera (with one spectral response per
channel), the scene and the quantity must come from the caller.
"""

from __future__ import annotations

import os
from typing import Optional, Tuple, Union

import numpy as np

from ..contract import QUANTITIES, RecordingError
from ..physics.camera import Camera
from .recording import Recording, Scene, Truth

__all__ = ["read_numpy", "read_tiff"]


def _require(
    path: str, quantity: Optional[str], camera: Optional[Camera], scene: Optional[Scene], what: str
) -> Tuple[str, Camera, Scene]:
    """The quantity, camera and scene a file of bare pixels needs, all given."""
    missing = [
        n for n, v in (("quantity", quantity), ("camera", camera), ("scene", scene)) if v is None
    ]
    if missing:
        raise RecordingError(
            path,
            ", ".join(missing),
            f"{what} holds only pixels: the {' and '.join(missing)} must be given",
            "pass quantity='radiance' (W/(m2 sr)) or 'radiometric_temperature' (K), "
            "camera=qogi.Camera(name, ifov_rad, [SpectralResponse per channel], frame_rate_hz) "
            "and scene=qogi.Scene(distance_m, ambient_temperature_K, pressure_Pa)",
        )
    if quantity not in QUANTITIES:
        raise RecordingError(
            path, "quantity", f"unknown quantity {quantity!r}", f"use one of {sorted(QUANTITIES)}"
        )
    assert quantity is not None and camera is not None and scene is not None  # checked above
    return quantity, camera, scene


def _finish(
    path: str,
    data: np.ndarray,
    time_s,
    quantity,
    camera,
    scene,
    truth,
    nonfinite,
    source_format: str,
) -> Recording:
    if data.ndim == 3:
        data = data[:, None]
    if data.ndim != 4:
        raise RecordingError(
            path,
            "frames",
            f"expected (T, C, H, W) or (T, H, W); got shape {data.shape}",
            "save frames as (time, channel, height, width)",
        )
    rec = Recording.from_arrays(
        data,
        time_s,
        quantity=quantity,
        camera=camera,
        scene=scene,
        truth=truth,
        nonfinite=nonfinite,
    )
    rec.path = path
    rec.attrs.update({"source": os.path.basename(path), "source_format": source_format})
    return rec


def read_numpy(
    path: Union[str, os.PathLike],
    *,
    quantity: Optional[str] = None,
    camera: Optional[Camera] = None,
    scene: Optional[Scene] = None,
    time_s=None,
    truth: Optional[Truth] = None,
    key: str = "frames",
    nonfinite: str = "error",
) -> Recording:
    """A recording from a numpy file.

    Parameters
    ----------
    path : .npy or .npz
        .npy: the frames, (T, C, H, W) or (T, H, W). .npz: array ``key``
        (default "frames"), and ``time_s`` if present and not given.
    quantity : {"radiance", "radiometric_temperature"}
        Required: what the values are (W/(m2 sr) or K).
    camera : Camera
        Required, with one SpectralResponse per channel.
    scene : Scene
        Required.
    time_s : array (T,), s, optional
        Default: from the .npz, else ``arange(T) / camera.frame_rate_hz``.
    truth : Truth, optional
    nonfinite : {"error", "invalid"}
    """
    p = os.fspath(path)
    if not os.path.isfile(p):
        raise RecordingError(p, "file", "does not exist", "check the path")
    quantity, camera, scene = _require(p, quantity, camera, scene, "a numpy file")
    try:
        loaded = np.load(p, mmap_mode="r", allow_pickle=False)
    except ValueError as e:
        raise RecordingError(p, "file", f"is not a numpy .npy/.npz file ({e})") from None
    if isinstance(loaded, np.lib.npyio.NpzFile):
        with loaded:
            if key not in loaded.files:
                raise RecordingError(
                    p,
                    key,
                    f"no array {key!r} in the archive (it has {loaded.files})",
                    "pass key='<name>'",
                )
            data = np.asarray(loaded[key])
            if time_s is None and "time_s" in loaded.files:
                time_s = np.asarray(loaded["time_s"])
        fmt = "numpy npz"
    else:
        data = loaded
        fmt = "numpy npy"
    if not (np.issubdtype(data.dtype, np.floating) or np.issubdtype(data.dtype, np.integer)):
        raise RecordingError(p, key, f"dtype {data.dtype} is not numeric")
    return _finish(p, data, time_s, quantity, camera, scene, truth, nonfinite, fmt)


def read_tiff(
    path: Union[str, os.PathLike],
    *,
    quantity: Optional[str] = None,
    camera: Optional[Camera] = None,
    scene: Optional[Scene] = None,
    time_s=None,
    scale: Optional[float] = None,
    offset: float = 0.0,
    truth: Optional[Truth] = None,
    nonfinite: str = "error",
) -> Recording:
    """A recording from a multi-page TIFF stack (read with OpenCV).

    Pages are frames; with C channels (``len(camera.channels)``) consecutive
    groups of C single-channel pages form one frame, or each page may itself
    hold C channels.

    Parameters
    ----------
    quantity, camera, scene, time_s, truth, nonfinite
        As :func:`read_numpy` (quantity, camera and scene required).
    scale, offset : float
        Integer pages are camera counts: value = scale * count + offset in
        the units of ``quantity`` (e.g. scale=0.04 for FLIR's 16-bit
        temperature TIFFs in K/count). Required for integer pages; applied to
        float pages too when given.
    """
    import cv2

    p = os.fspath(path)
    if not os.path.isfile(p):
        raise RecordingError(p, "file", "does not exist", "check the path")
    quantity, camera, scene = _require(p, quantity, camera, scene, "a TIFF stack")
    ok, pages = cv2.imreadmulti(p, flags=cv2.IMREAD_UNCHANGED)
    if not ok or not pages:
        raise RecordingError(p, "file", "is not a TIFF that OpenCV can read")
    shapes = {pg.shape for pg in pages}
    if len(shapes) != 1:
        raise RecordingError(p, "pages", f"pages have different shapes {sorted(shapes)}")
    stack = np.stack(pages)
    if np.issubdtype(stack.dtype, np.integer) and scale is None:
        raise RecordingError(
            p,
            "pages",
            f"pages are integers ({stack.dtype}): camera counts, not "
            f"{quantity} [{QUANTITIES[quantity]}]",
            "pass scale= and offset= (value = scale * count + offset)",
        )
    data: np.ndarray = stack.astype(np.float64 if scale is not None else np.float32)
    if scale is not None:
        data = data * float(scale) + float(offset)
    n_ch = len(camera.channels)
    if data.ndim == 4:  # (T, H, W, C) pages
        data = np.moveaxis(data, -1, 1)
    elif n_ch > 1:
        if data.shape[0] % n_ch:
            raise RecordingError(
                p,
                "pages",
                f"{data.shape[0]} pages is not a multiple of the {n_ch} channels",
                "write C pages per frame",
            )
        data = data.reshape((-1, n_ch) + data.shape[1:])
    return _finish(p, data, time_s, quantity, camera, scene, truth, nonfinite, "TIFF")
