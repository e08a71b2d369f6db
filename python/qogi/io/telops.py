"""Telops .hcc files (FAST series cameras, including the M150 filter wheel).

An .hcc file is frames one after another, each a header of
``ImageHeaderLength`` bytes followed by Width x Height little-endian uint16
pixels. The header layout is public in code: the MIT-licensed ``fasthcc``
package (header.py: the first 108 bytes, versions 10-12) and CEA's librir
(HCCLoader.h: the packed struct to byte 200, with the filter-wheel position
and the calibration modes). qogi reads it with its own code; the offsets
used (all little-endian):

======  ======  ============================  ===================================
offset  type    field                         meaning
======  ======  ============================  ===================================
0       2 char  Signature                     ``TC``
2       u8      DeviceXMLMinorVersion         header version, minor
3       u8      DeviceXMLMajorVersion         header version, major
4       u16     ImageHeaderLength             bytes of header before the pixels
8       u32     FrameID                       frame counter
12      f32     DataOffset                    value = pixel * 2**DataExp + DataOffset
16      i8      DataExp
24      u32     ExposureTime                  10 ns units (/100 = us)
28      u8      CalibrationMode               0 Raw0, 1 NUC, 2 RT [K], 3 IBR
                                              [W/(m2 sr)], 4 IBI [W/m2], 5 Raw
32      u16     Width, 34 u16 Height          pixels
44      u32     AcquisitionFrameRate          mHz
75      u8      FWMode                        0 fixed, else the wheel turns
76      u16     FWSpeedSetpoint, 78 FWSpeed   wheel speed [RPM]
100     u32     POSIXTime                     s since 1970 (UTC)
104     u32     SubSecondTime                 100 ns ticks
128     u8      FWPosition                    filter-wheel position of this frame
130     u8      NDFilterPosition
156     f32     ExternalBlackBodyTemperature
======  ======  ============================  ===================================

Every frame carries its own DataOffset/DataExp (the camera may change them
in mid-sequence), time stamp and filter position: each is used per frame.
Pixel words >= 0xFFF1 are flagged bad pixels (librir); they become NaN.
"""

from __future__ import annotations

import math
import os
import struct
from typing import Any, Dict, Iterable, List, Optional, Sequence, Tuple, Union

import numpy as np

from ..errors import DataError
from ..files import atomic_open

__all__ = [
    "HccFile",
    "open_hcc",
    "write_hcc",
    "hcc_header",
    "HEADER_FIELDS",
    "CALIBRATION_MODES",
    "wheel_turns",
    "HccFormatError",
]

#: (name, offset, numpy little-endian type) of the header fields qogi reads.
HEADER_FIELDS: Tuple[Tuple[str, int, str], ...] = (
    ("DeviceXMLMinorVersion", 2, "u1"),
    ("DeviceXMLMajorVersion", 3, "u1"),
    ("ImageHeaderLength", 4, "<u2"),
    ("FrameID", 8, "<u4"),
    ("DataOffset", 12, "<f4"),
    ("DataExp", 16, "i1"),
    ("ExposureTime", 24, "<u4"),
    ("CalibrationMode", 28, "u1"),
    ("Width", 32, "<u2"),
    ("Height", 34, "<u2"),
    ("AcquisitionFrameRate", 44, "<u4"),
    ("FWMode", 75, "u1"),
    ("FWSpeedSetpoint", 76, "<u2"),
    ("FWSpeed", 78, "<u2"),
    ("POSIXTime", 100, "<u4"),
    ("SubSecondTime", 104, "<u4"),
    ("FWPosition", 128, "u1"),
    ("NDFilterPosition", 130, "u1"),
    ("ExternalBlackBodyTemperature", 156, "<f4"),
)
#: CalibrationMode -> (name, qogi quantity or None when not usable, unit).
CALIBRATION_MODES = {
    0: ("Raw0", None, "counts"),
    1: ("NUC", None, "counts"),
    2: ("RT", "radiometric_temperature", "K"),
    3: ("IBR", "radiance", "W/(m2 sr)"),
    4: ("IBI", "irradiance", "W/m2"),
    5: ("Raw", None, "counts"),
}
#: Smallest pixel word that marks a bad pixel.
BAD_PIXEL = 0xFFF1
#: SubSecondTime ticks per second.
TICKS_PER_S = 10_000_000
_MIN_HEADER = 160  # bytes: every field above fits


class HccFormatError(DataError):
    """An .hcc file that cannot be read (names the file, frame and problem)."""


class HccFile:
    """A Telops .hcc file opened for reading (memory-mapped).

    Attributes: ``width``, ``height``, ``n_frames``, ``version`` (major,
    minor), ``header_length``, ``trailing_bytes`` (after the last whole
    frame). :meth:`fields` gives every frame's header fields at once;
    :meth:`counts` and :meth:`values` read frames.
    """

    def __init__(self, path: Union[str, os.PathLike]):
        self.path = os.fspath(path)
        if not os.path.isfile(self.path):
            raise FileNotFoundError(f"{self.path}: no such file")
        size = os.path.getsize(self.path)
        with open(self.path, "rb") as fh:
            head = fh.read(_MIN_HEADER)
        if len(head) < 48 or head[:2] != b"TC":
            raise HccFormatError(
                f"{self.path}: not a Telops .hcc file (starts with "
                f"{head[:2]!r}; expected the signature 'TC')"
            )
        self.version = (head[3], head[2])
        self.header_length = struct.unpack_from("<H", head, 4)[0]
        self.width, self.height = struct.unpack_from("<HH", head, 32)
        if self.version[0] < 10:
            raise HccFormatError(
                f"{self.path}: header version {self.version[0]}.{self.version[1]} predates "
                "per-frame time stamps (version 10); re-export it with Telops Reveal IR"
            )
        if self.width == 0 or self.height == 0:
            raise HccFormatError(
                f"{self.path}: frame 0 header gives a {self.width}x{self.height} image"
            )
        if self.header_length < _MIN_HEADER:
            raise HccFormatError(
                f"{self.path}: ImageHeaderLength {self.header_length} bytes is "
                f"shorter than the {_MIN_HEADER}-byte layout read here"
            )
        self.stride = self.header_length + 2 * self.width * self.height
        self.n_frames = size // self.stride
        self.trailing_bytes = size - self.n_frames * self.stride
        if self.n_frames == 0:
            raise HccFormatError(
                f"{self.path}: {size} bytes, less than one frame of "
                f"{self.stride} bytes ({self.width}x{self.height})"
            )
        names = [f[0] for f in HEADER_FIELDS] + ["pixels"]
        formats = [f[2] for f in HEADER_FIELDS] + [("<u2", (self.height, self.width))]
        offsets = [f[1] for f in HEADER_FIELDS] + [self.header_length]
        self._dtype = np.dtype(
            {"names": names, "formats": formats, "offsets": offsets, "itemsize": self.stride}
        )
        self._map: Optional[np.memmap] = np.memmap(
            self.path, dtype=self._dtype, mode="r", shape=(self.n_frames,)
        )
        f = self.fields()
        bad = np.flatnonzero(
            (f["Width"] != self.width)
            | (f["Height"] != self.height)
            | (f["ImageHeaderLength"] != self.header_length)
        )
        if bad.size:
            i = int(bad[0])
            raise HccFormatError(
                f"{self.path}: frame {i} header says {f['Width'][i]}x"
                f"{f['Height'][i]} with a {f['ImageHeaderLength'][i]}-byte "
                f"header, unlike frame 0 ({self.width}x{self.height}, "
                f"{self.header_length}): a corrupt or concatenated file"
            )

    def fields(self, start: int = 0, stop: Optional[int] = None) -> Dict[str, np.ndarray]:
        """Header fields of frames ``start:stop``: name -> array, as stored
        (ExposureTime in 10 ns, AcquisitionFrameRate in mHz, SubSecondTime in
        100 ns ticks). Also ``time_s`` (POSIX seconds, float64)."""
        m = self._frames()[start:stop]
        out = {name: np.array(m[name]) for name, _, _ in HEADER_FIELDS}
        out["time_s"] = (
            out["POSIXTime"].astype(np.float64)
            + out["SubSecondTime"].astype(np.float64) / TICKS_PER_S
        )
        return out

    def counts(self, start: int, stop: int) -> np.ndarray:
        """Pixel words of frames ``start:stop`` (n, H, W) uint16, as stored."""
        return np.array(self._frames()[start:stop]["pixels"])

    def values(self, index: Union[int, Sequence[int]]) -> np.ndarray:
        """Calibrated values of the given frame(s), float64 (n, H, W): pixel *
        2**DataExp + DataOffset with each frame's own scaling; bad pixels NaN."""
        idx = np.atleast_1d(np.asarray(index, dtype=np.int64))
        rows = self._frames()[idx]
        px = np.array(rows["pixels"])
        scale = np.ldexp(1.0, rows["DataExp"].astype(np.int64))[:, None, None]
        off = rows["DataOffset"].astype(np.float64)[:, None, None]
        out = px.astype(np.float64) * scale + off
        out[px >= BAD_PIXEL] = np.nan
        return out

    def _frames(self) -> np.memmap:
        if self._map is None:
            raise ValueError(f"{self.path}: the file is closed")
        return self._map

    def close(self) -> None:
        m = getattr(self, "_map", None)
        if m is not None:
            mm = getattr(m, "_mmap", None)
            self._map = None
            del m
            if mm is not None:
                try:
                    mm.close()
                except BufferError:  # a view is still alive; the GC closes it
                    pass

    def __len__(self) -> int:
        return self.n_frames

    def __enter__(self) -> HccFile:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return (
            f"HccFile({self.path!r}, {self.n_frames} frames, {self.width}x{self.height}, "
            f"v{self.version[0]}.{self.version[1]})"
        )


def open_hcc(path: Union[str, os.PathLike]) -> HccFile:
    """Open a Telops .hcc file for reading."""
    return HccFile(path)


# --------------------------------------------------------------------------- writing


def hcc_header(
    *,
    width: int,
    height: int,
    header_length: Optional[int] = None,
    version: Tuple[int, int] = (12, 1),
    **fields,
) -> bytes:
    """One frame header: ``fields`` (names of :data:`HEADER_FIELDS`, values
    as stored) at their offsets; everything else zero. ``header_length``
    defaults to two image lines (4 x width bytes, Telops' convention), at
    least 160."""
    if header_length is None:
        header_length = 4 * width
        while header_length < _MIN_HEADER:
            header_length += 4 * width
    buf = bytearray(header_length)
    buf[0:2] = b"TC"
    values = {
        "DeviceXMLMajorVersion": version[0],
        "DeviceXMLMinorVersion": version[1],
        "ImageHeaderLength": header_length,
        "Width": width,
        "Height": height,
    }
    values.update(fields)
    known = {name: (off, typ) for name, off, typ in HEADER_FIELDS}
    for name, v in values.items():
        if name not in known:
            raise ValueError(f"unknown .hcc header field {name!r}")
        off, typ = known[name]
        np.frombuffer(buf, dtype=typ, count=1, offset=off)[:] = v
    return bytes(buf)


def _scaling(v: np.ndarray, max_word: int = BAD_PIXEL - 1) -> Tuple[float, int]:
    """DataOffset and DataExp for one frame: the finest power-of-two step
    that spans the frame's values with words below the bad-pixel mark."""
    finite = v[np.isfinite(v)]
    if finite.size == 0:
        return 0.0, 0
    lo, hi = float(finite.min()), float(finite.max())
    offset = float(np.float32(lo))
    if offset > lo:
        offset = float(np.nextafter(np.float32(lo), np.float32(-np.inf)))
    span = max(hi - offset, 1e-30)
    exp = math.ceil(math.log2(span / max_word))
    while (hi - offset) / 2.0**exp > max_word:
        exp += 1
    return offset, max(-128, min(127, exp))


def write_hcc(
    path: Union[str, os.PathLike],
    frames: Iterable[np.ndarray],
    time_s: Sequence[float],
    *,
    calibration_mode: int = 2,
    fw_positions: Optional[Sequence[int]] = None,
    frame_rate_hz: float = 100.0,
    exposure_time_us: float = 100.0,
    fw_speed_rpm: int = 0,
    version: Tuple[int, int] = (12, 1),
) -> int:
    """Write a Telops .hcc file (atomically), frame by frame.

    Parameters
    ----------
    frames : iterable of (H, W) float arrays
        Calibrated values in the mode's unit (RT: K; IBR: W/(m2 sr); IBI:
        W/m2), or uint16 words for the raw modes (0, 1, 5). NaN pixels are
        written as bad pixels (0xFFFF).
    time_s : sequence of float
        POSIX time [s] of each frame (stored as seconds + 100 ns ticks).
    calibration_mode : int
        :data:`CALIBRATION_MODES` key.
    fw_positions : sequence of int, optional
        Filter-wheel position of each frame (FWMode 1 when given).
    Each frame gets its own DataOffset and DataExp (the finest step spanning
    its values). Returns the number of frames written.
    """
    n = 0
    with atomic_open(path, "wb") as fh:
        for i, v in enumerate(frames):
            a = np.asarray(v)
            h, w = a.shape
            if calibration_mode in (0, 1, 5):
                words, off, exp = a.astype(np.uint16), 0.0, 0
            else:
                a = a.astype(np.float64)
                off, exp = _scaling(a)
                with np.errstate(invalid="ignore"):
                    q = np.rint((a - off) / 2.0**exp)
                words = np.where(np.isfinite(q), np.clip(q, 0, BAD_PIXEL - 1), 0xFFFF).astype("<u2")
            t = float(time_s[i])
            sec = math.floor(t)
            ticks = int(round((t - sec) * TICKS_PER_S))
            if ticks >= TICKS_PER_S:
                sec, ticks = sec + 1, ticks - TICKS_PER_S
            fields: Dict[str, Any] = dict(
                FrameID=i,
                DataOffset=off,
                DataExp=exp,
                ExposureTime=int(round(exposure_time_us * 100)),
                CalibrationMode=calibration_mode,
                AcquisitionFrameRate=int(round(frame_rate_hz * 1000)),
                POSIXTime=sec,
                SubSecondTime=ticks,
            )
            if fw_positions is not None:
                fields.update(
                    FWMode=1,
                    FWPosition=int(fw_positions[i]),
                    FWSpeedSetpoint=fw_speed_rpm,
                    FWSpeed=fw_speed_rpm,
                )
            fh.write(hcc_header(width=w, height=h, version=version, **fields))
            fh.write(words.astype("<u2").tobytes())
            n += 1
    if n == 0:
        raise ValueError(f"{os.fspath(path)}: no frame to write")
    return n


# --------------------------------------------------------------------------- filter wheel


def wheel_turns(positions: np.ndarray) -> Tuple[List[int], np.ndarray, int]:
    """Group frames by wheel turn.

    Parameters
    ----------
    positions : (N,) int
        Filter position of each frame, in file order.

    Returns
    -------
    order : list of int
        The positions in the order the wheel shows them (from the first
        turn); channel k of the recording is position ``sorted(order)[k]``.
    turns : (T, C) int
        File frame index of each channel's frame, one row per complete turn,
        columns in sorted-position order.
    skipped : int
        Frames left out because their turn was incomplete (a dropped frame).
    """
    pos = np.asarray(positions, dtype=np.int64)
    distinct = sorted(set(pos.tolist()))
    c = len(distinct)
    # The wheel order: positions as they first follow one another.
    order: List[int] = []
    for p in pos.tolist():
        if p in order:
            break
        order.append(p)
    if len(order) != c:
        order = distinct
    col = {p: distinct.index(p) for p in distinct}
    turns, i, used = [], 0, 0
    n = len(pos)
    while i < n:
        if pos[i] != order[0]:
            i += 1
            continue
        seq = pos[i : i + c].tolist()
        if seq == order:
            row = [0] * c
            for k, p in enumerate(order):
                row[col[p]] = i + k
            turns.append(row)
            used += c
            i += c
        else:
            i += 1
    return order, np.asarray(turns, dtype=np.int64).reshape(-1, c), n - used
