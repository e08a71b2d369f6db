"""The qogi recording file (HDF5, docs/recording.md) written frame by frame
(:class:`RecordingWriter`, for generators and converters).
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING, Optional, Sequence, Union

import numpy as np

from ..contract import (
    FORMAT,
    QUANTITIES,
    SCENE_OPTIONAL,
    SCENE_REQUIRED,
    VERSION,
    RecordingError,
    check_frame_rate,
    first_nonfinite,
    typical_interval,
)
from ..errors import is_no_space
from ..files import atomic_path
from ..hdf5_files import GuardedFile, _h5py, set_attr
from ..physics.camera import check_channels

if TYPE_CHECKING:  # for the signatures only: the model (io.recording) imports this writer
    from ..physics.camera import Camera
    from .recording import Scene, Truth


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
    for name in SCENE_REQUIRED + SCENE_OPTIONAL:
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
        check_channels(camera.channels, self.path, shape[0])
        if not overwrite and os.path.exists(self.path):
            raise FileExistsError(f"{self.path} exists (pass overwrite=True to replace it)")
        self.quantity, self.camera, self.scene = quantity, camera, scene
        self.frame_shape = shape
        self.allow_nonfinite = allow_nonfinite
        self._n = 0
        self._last_t = -math.inf
        self.keep_partial = bool(keep_partial)

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
                loc = first_nonfinite(a)
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
            check_frame_rate(self.path, t, rate)
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
