"""Readers that turn camera and array files into :class:`qogi.Recording`.

- FLIR radiometric files (.seq, .csq, .fff, radiometric .jpg):
  :func:`read_flir` / :func:`open_flir` give raw counts bit-exactly with each
  frame's calibration; :func:`read_flir_recording` converts to a recording.
- numpy .npy/.npz: :func:`read_numpy`; multi-page TIFF: :func:`read_tiff`.
- Telops .hcc (FAST series, filter wheel): :func:`open_hcc`, :func:`write_hcc`.
- :func:`qogi.open_recording` (:mod:`qogi.io.open`) opens any of these
  camera files lazily as a recording; :func:`read_recording` picks the
  reader by the file's first bytes (one registry of formats,
  :data:`qogi.io.open.FORMATS`).

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
from .open import FORMATS, file_format, file_kind
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

#: Extensions of the FLIR and Telops files (from the reader registry,
#: :data:`qogi.io.open.FORMATS`).
FLIR_EXTENSIONS = file_format("flir").extensions
TELOPS_EXTENSIONS = file_format("telops").extensions


def read_recording(path: Union[str, os.PathLike], **kwargs) -> Recording:
    """Open any supported file as a recording, recognised by its first bytes
    (:func:`qogi.io.open.file_kind`, the reader registry).

    qogi HDF5 -> :func:`qogi.open_recording`; FLIR .seq/.csq/.fff/.jpg ->
    :func:`read_flir_recording`; Telops .hcc -> :func:`qogi.open_recording`
    (camera=..., distance_m=..., ambient_temperature_K=...); numpy .npy/.npz ->
    :func:`read_numpy`; TIFF -> :func:`read_tiff`. Keyword arguments go to
    that reader.
    """
    kind = file_kind(path)
    if kind == "hdf5":
        return open_recording(path, **kwargs)
    if kind == "flir":
        return read_flir_recording(path, **kwargs)
    if kind == "telops":
        return open_camera_file(path, **kwargs)
    if kind == "numpy":
        return read_numpy(path, **kwargs)
    if kind == "tiff":
        return read_tiff(path, **kwargs)
    ext = os.path.splitext(os.fspath(path))[1].lower()
    raise ValueError(
        f"{path}: unknown recording file type {ext!r}, by its name and its first bytes "
        "(known: " + "; ".join(f.description for f in FORMATS) + ")"
    )
