"""Readers that turn camera and array files into :class:`qogi.Recording`.

- FLIR radiometric files (.seq, .csq, .fff, radiometric .jpg):
  :func:`read_flir` / :func:`open_flir` give raw counts bit-exactly with each
  frame's calibration; :func:`read_flir_recording` converts to a recording.
- numpy .npy/.npz: :func:`read_numpy`; multi-page TIFF: :func:`read_tiff`.
- Telops .hcc (FAST series, filter wheel): :func:`open_hcc`, :func:`write_hcc`.
- :func:`qogi.open_recording` (:mod:`qogi.io.open`) opens any of these
  camera files lazily as a recording; :func:`read_recording` picks the
  reader from the file name.

Camera files do not carry everything a recording needs (the spectral
response, the pressure ...): the readers ask for it by name.
"""

from __future__ import annotations

import os
from typing import Union

from .arrays import read_numpy, read_tiff
from .flir import (
    FlirFile,
    FlirFrame,
    FlirMetadata,
    flir_apparent_temperature,
    flir_raw_from_temperature,
    flir_temperature,
    open_flir,
    read_flir,
    read_flir_recording,
)
from .flir_writer import write_flir_seq
from .hdf5 import open_recording
from .open import open_recording as open_camera_file
from .recording import Recording
from .telops import HccFile, open_hcc, write_hcc

__all__ = [
    "read_recording",
    "read_numpy",
    "read_tiff",
    "read_flir",
    "open_flir",
    "read_flir_recording",
    "flir_temperature",
    "flir_apparent_temperature",
    "flir_raw_from_temperature",
    "FlirFile",
    "FlirFrame",
    "FlirMetadata",
    "open_hcc",
    "write_hcc",
    "HccFile",
    "write_flir_seq",
]

FLIR_EXTENSIONS = (".seq", ".csq", ".fff", ".jpg", ".jpeg")
TELOPS_EXTENSIONS = (".hcc",)


def read_recording(path: Union[str, os.PathLike], **kwargs) -> Recording:
    """Open any supported file as a recording, by its extension.

    .h5/.hdf5 -> :func:`qogi.open_recording`; .seq/.csq/.fff/.jpg ->
    :func:`read_flir_recording`; .hcc -> :func:`qogi.open_recording`
    (camera=..., distance_m=..., ambient_temperature_K=...); .npy/.npz -> :func:`read_numpy`;
    .tif/.tiff -> :func:`read_tiff`. Keyword arguments go to that reader.
    """
    ext = os.path.splitext(os.fspath(path))[1].lower()
    if ext in (".h5", ".hdf5", ".hdf"):
        return open_recording(path, **kwargs)
    if ext in FLIR_EXTENSIONS:
        return read_flir_recording(path, **kwargs)
    if ext in TELOPS_EXTENSIONS:
        return open_camera_file(path, **kwargs)
    if ext in (".npy", ".npz"):
        return read_numpy(path, **kwargs)
    if ext in (".tif", ".tiff"):
        return read_tiff(path, **kwargs)
    raise ValueError(
        f"{path}: unknown recording file type {ext!r} (known: .h5, .seq, .csq, "
        ".fff, .jpg, .npy, .npz, .tif)"
    )
