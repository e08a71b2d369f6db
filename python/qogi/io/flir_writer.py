"""qogi's FLIR .seq writer: FFF blocks, one per frame, as FLIR cameras write them.

Made to build test files with exact truth (no public MWIR gas-camera sample
exists) and to export synthetic releases to tools that read FLIR files. The
layout is the one :mod:`qogi.io.flir` reads, as documented by ExifTool's FLIR
module:

- FFF header (64 bytes, big-endian like FLIR's): ``FFF\\0``, creator (16
  bytes), version 100 at 0x14, record directory offset at 0x18 and its
  number of entries at 0x1C.
- Record directory: 32-byte entries (type u16, subtype u16, version u32,
  index u32, offset u32 from the block start, length u32, parent, object
  number, checksum).
- RawData record (type 0x01): 32-byte header (byte-order mark 0x0002,
  width, height) then the counts as plain 16-bit words.
- CameraInfo record (type 0x20, 0x480 bytes): the byte-order mark, then the
  object parameters, Planck constants, names, field of view and the time
  stamp (Unix seconds, milliseconds, time-zone offset) at ExifTool's offsets.

``byte_order`` chooses how the records' words are stored ("<" as FLIR's
cameras, ">" for the big-endian variant some tools write); the FFF header
can be written in either order too (``header_order``).
"""

from __future__ import annotations

import math
import os
import struct
from dataclasses import replace
from typing import Any, Dict, Iterable, Optional, Sequence, Union

import numpy as np

from ..files import atomic_open
from .flir import C2_CM_K, FlirMetadata

__all__ = [
    "write_flir_seq",
    "fff_block",
    "planck_calibration_for",
    "flir_metadata",
    "raw_from_apparent_temperature",
    "write_recording_as_seq",
]

_CAMERA_INFO_LEN = 0x480


def _put_str(buf: bytearray, off: int, size: int, s: str) -> None:
    b = s.encode("latin-1")[: size - 1]
    buf[off : off + len(b)] = b


def _camera_info(m: FlirMetadata, order: str) -> bytes:
    rec = bytearray(_CAMERA_INFO_LEN)
    struct.pack_into(order + "H", rec, 0, 2)

    def f32(o, v):
        struct.pack_into(order + "f", rec, o, float(v))

    def u16(o, v):
        struct.pack_into(order + "H", rec, o, int(v))

    f32(0x20, m.emissivity)
    f32(0x24, m.object_distance_m)
    f32(0x28, m.reflected_temperature_K)
    f32(0x2C, m.atmospheric_temperature_K)
    f32(0x30, m.ir_window_temperature_K)
    f32(0x34, m.ir_window_transmission)
    f32(0x3C, m.relative_humidity)
    f32(0x58, m.planck_r1)
    f32(0x5C, m.planck_b)
    f32(0x60, m.planck_f)
    f32(0x70, m.atmospheric_trans_alpha1)
    f32(0x74, m.atmospheric_trans_alpha2)
    f32(0x78, m.atmospheric_trans_beta1)
    f32(0x7C, m.atmospheric_trans_beta2)
    f32(0x80, m.atmospheric_trans_x)
    f32(0x90, m.camera_temperature_range_max_K)
    f32(0x94, m.camera_temperature_range_min_K)
    _put_str(rec, 0xD4, 32, m.camera_model)
    _put_str(rec, 0xF4, 16, m.camera_part_number)
    _put_str(rec, 0x104, 16, m.camera_serial_number)
    _put_str(rec, 0x114, 16, m.camera_software)
    _put_str(rec, 0x170, 32, m.lens_model)
    _put_str(rec, 0x190, 16, m.lens_part_number)
    _put_str(rec, 0x1A0, 16, m.lens_serial_number)
    f32(0x1B4, m.field_of_view_deg)
    _put_str(rec, 0x1EC, 16, m.filter_model)
    struct.pack_into(order + "i", rec, 0x308, int(round(m.planck_o)))
    f32(0x30C, m.planck_r2)
    u16(0x310, m.raw_value_range_min)
    u16(0x312, m.raw_value_range_max)
    u16(0x338, m.raw_value_median)
    u16(0x33C, m.raw_value_range)
    sec = math.floor(m.timestamp_s)
    ms = int(round((m.timestamp_s - sec) * 1000.0))
    if ms == 1000:
        sec, ms = sec + 1, 0
    struct.pack_into(order + "IIh", rec, 0x384, int(sec), ms, -int(m.utc_offset_min))
    f32(0x45C, m.focus_distance_m)
    u16(0x464, m.frame_rate_hz)
    return bytes(rec)


def fff_block(
    raw: np.ndarray,
    metadata: FlirMetadata,
    *,
    byte_order: str = "<",
    header_order: str = ">",
    creator: str = "qogi",
) -> bytes:
    """One FFF block: header, a two-entry record directory, RawData and
    CameraInfo. ``raw`` is (H, W) uint16 counts."""
    a = np.asarray(raw)
    if a.ndim != 2 or a.dtype != np.uint16:
        raise ValueError(f"raw must be a 2-D uint16 array of counts; got {a.dtype} {a.shape}")
    if byte_order not in "<>" or header_order not in "<>":
        raise ValueError("byte_order and header_order must be '<' or '>'")
    h, w = a.shape
    raw_rec = bytearray(32)
    struct.pack_into(byte_order + "HHH", raw_rec, 0, 2, w, h)
    raw_rec += a.astype(byte_order + "u2").tobytes()
    cam_rec = _camera_info(replace(metadata, width=w, height=h), byte_order)
    dir_off, n = 0x40, 2
    raw_off = dir_off + 32 * n
    cam_off = raw_off + len(raw_rec)
    header = bytearray(0x40)
    header[0:4] = b"FFF\x00"
    _put_str(header, 4, 16, creator)
    struct.pack_into(header_order + "III", header, 0x14, 100, dir_off, n)
    struct.pack_into(header_order + "I", header, 0x20, n + 1)
    directory = bytearray()
    for idx, (rtype, off, length) in enumerate(
        ((0x01, raw_off, len(raw_rec)), (0x20, cam_off, len(cam_rec))), start=1
    ):
        e = bytearray(32)
        struct.pack_into(
            header_order + "HHIIII", e, 0, rtype, 1 if rtype == 1 else 0, 100, idx, off, length
        )
        directory += e
    return bytes(header + directory + raw_rec + cam_rec)


def write_flir_seq(
    path: Union[str, os.PathLike],
    frames: Iterable[np.ndarray],
    metadata: Union[FlirMetadata, Sequence[FlirMetadata]],
    *,
    byte_order: str = "<",
    header_order: str = ">",
) -> int:
    """Write a FLIR .seq file (atomically): one FFF block per frame.

    Parameters
    ----------
    path : str or path
    frames : iterable of (H, W) uint16
        Raw counts, streamed (one frame in memory at a time).
    metadata : FlirMetadata or sequence of FlirMetadata
        One per frame (each frame's own time stamp and parameters), or one
        for all (then every frame gets the same time stamp: give a sequence
        to have per-frame times).
    byte_order, header_order : {"<", ">"}
        Byte order of the records and of the FFF header.

    Returns the number of frames written.
    """
    n = 0
    with atomic_open(path, "wb") as fh:
        for i, raw in enumerate(frames):
            m = metadata if isinstance(metadata, FlirMetadata) else metadata[i]
            fh.write(fff_block(raw, m, byte_order=byte_order, header_order=header_order))
            n += 1
    if n == 0:
        raise ValueError(f"{os.fspath(path)}: no frame to write")
    return n


def planck_calibration_for(
    centroid_cm1: float, max_temperature_K: float = 345.0, offset_counts: float = -1000.0
) -> dict:
    """Planck constants (R1, R2, B, F, O) of a FLIR-like one-line calibration
    raw(T) = R1 / (R2 (exp(B/T) - F)) - O for a camera whose band is centred at
    ``centroid_cm1`` [cm-1]: B = c2 nu (so the file's effective band is the
    camera's), F = 1, R2 = 1, and R1 so that ``max_temperature_K`` [K] gives
    the top of the 16-bit range."""
    b = C2_CM_K * float(centroid_cm1)
    r1 = (65000.0 + offset_counts) * (math.exp(b / max_temperature_K) - 1.0)
    return {
        "planck_r1": r1,
        "planck_r2": 1.0,
        "planck_b": b,
        "planck_f": 1.0,
        "planck_o": float(offset_counts),
    }


def flir_metadata(
    *,
    width: int,
    height: int,
    timestamp_s: float,
    planck: dict,
    field_of_view_deg: float,
    frame_rate_hz: int,
    object_distance_m: float = 1.0,
    atmospheric_temperature_K: float = 293.15,
    camera_model: str = "qogi synthetic",
    lens_model: str = "",
    **extra,
) -> FlirMetadata:
    """A :class:`FlirMetadata` with FLIR's defaults for the object parameters
    (emissivity 1, distance 1 m, 20 C, RH 50 %, FLIR's atmospheric constants)
    unless given."""
    d: Dict[str, Any]
    d = dict(
        width=width,
        height=height,
        emissivity=1.0,
        object_distance_m=object_distance_m,
        reflected_temperature_K=293.15,
        atmospheric_temperature_K=atmospheric_temperature_K,
        ir_window_temperature_K=293.15,
        ir_window_transmission=1.0,
        relative_humidity=0.5,
        atmospheric_trans_alpha1=0.006569,
        atmospheric_trans_alpha2=0.01262,
        atmospheric_trans_beta1=-0.002276,
        atmospheric_trans_beta2=-0.00667,
        atmospheric_trans_x=1.9,
        camera_temperature_range_max_K=423.15,
        camera_temperature_range_min_K=253.15,
        camera_model=camera_model,
        camera_part_number="",
        camera_serial_number="0",
        camera_software="qogi",
        lens_model=lens_model,
        lens_part_number="",
        lens_serial_number="",
        filter_model="",
        field_of_view_deg=field_of_view_deg,
        focus_distance_m=0.0,
        frame_rate_hz=int(frame_rate_hz),
        raw_value_range_min=0,
        raw_value_range_max=65535,
        raw_value_median=0,
        raw_value_range=0,
        timestamp_s=timestamp_s,
        utc_offset_min=0,
    )
    d.update(planck)
    d.update(extra)
    return FlirMetadata(**d)


def raw_from_apparent_temperature(temperature_K: np.ndarray, metadata: FlirMetadata) -> np.ndarray:
    """Counts (uint16, rounded, clipped to 0..65535) whose apparent
    temperature (:func:`qogi.io.flir.flir_apparent_temperature`) is
    ``temperature_K`` [K]: the inverse of the one-line Planck law."""
    t = np.asarray(temperature_K, dtype=np.float64)
    m = metadata
    raw = m.planck_r1 / (m.planck_r2 * (np.exp(m.planck_b / t) - m.planck_f)) - m.planck_o
    return np.clip(np.rint(raw), 0, 65535).astype(np.uint16)


def write_recording_as_seq(
    recording,
    path: Union[str, os.PathLike],
    *,
    start_time_s: float = 1.7e9,
    object_distance_m: float = 1.0,
    atmospheric_temperature_K: Optional[float] = None,
    max_temperature_K: float = 345.0,
    camera_model: str = "",
    byte_order: str = "<",
) -> int:
    """Export a one-channel :class:`qogi.Recording` as a FLIR .seq: each
    frame's radiometric temperature through the channel becomes counts of a
    calibration centred on the channel (:func:`planck_calibration_for`), each
    frame stamped with its own time (``start_time_s`` + ``time_s``, to the
    millisecond, as FLIR stores it). The field of view is IFOV x width."""
    if recording.n_channels != 1:
        raise ValueError(
            f"a FLIR .seq holds one channel; this recording has {recording.n_channels}"
        )
    ch = recording.channels[0]
    planck = planck_calibration_for(ch.centroid_cm1, max_temperature_K)
    _, _, h, w = recording.shape
    atm = (
        recording.scene.ambient_temperature_K
        if atmospheric_temperature_K is None
        else atmospheric_temperature_K
    )
    metas = [
        flir_metadata(
            width=w,
            height=h,
            timestamp_s=start_time_s + float(t),
            planck=planck,
            field_of_view_deg=math.degrees(recording.camera.ifov_rad * w),
            frame_rate_hz=int(round(recording.camera.frame_rate_hz)),
            object_distance_m=object_distance_m,
            atmospheric_temperature_K=atm,
            camera_model=camera_model or recording.camera.name,
        )
        for t in recording.time_s
    ]

    def frames():
        for i in range(recording.n_frames):
            yield raw_from_apparent_temperature(
                recording.frame(i, quantity="radiometric_temperature")[0], metas[i]
            )

    return write_flir_seq(path, frames(), metas, byte_order=byte_order)
