"""FLIR radiometric files: .seq and .csq sequences, radiometric JPEG, FFF.

All of them are made of FFF blocks ("FLIR file format"): a 64-byte header
(``FFF\\0``, creator, version 100-199 which also tells the byte order, the
offset and length of a record directory), then records of 32-byte directory
entries (type, subtype, version, offset, length). Two records matter here
(layout as documented by ExifTool's FLIR module):

- RawData (type 0x01): a 32-byte header (byte-order mark 0x0002, width,
  height) followed by the sensor's raw 16-bit counts, either as plain
  little/big-endian words (.seq, most JPEGs), a PNG (some JPEGs) or a
  JPEG-LS codestream (.csq; decoded by the engine's T.87 decoder,
  :func:`qogi._engine.decode_jpegls`).
- CameraInfo (type 0x20): the calibration and object parameters of that
  frame: Planck constants R1, R2, B, F, O; emissivity, object distance,
  reflected, atmospheric and IR-window temperatures, window transmission,
  relative humidity, the atmospheric transmission constants (alpha1/2,
  beta1/2, X); camera, lens and filter names; field of view; time stamp.

A .seq or .csq file is FFF blocks one after another, one per frame; a
radiometric JPEG carries one FFF block split over APP1 segments tagged
``FLIR\\0``.

Raw counts to temperature (:func:`flir_temperature`), as FLIR's cameras
and tools do it and as Thermimage's ``raw2temp`` and flirpy implement it:
the camera is calibrated so that a blackbody at temperature T gives

    raw(T) = R1 / (R2 (exp(B / T) - F)) - O

(a one-wavenumber Planck law; B = c2 nu_eff, so the camera's effective
wavenumber is B / c2). The object's signal is recovered from the measured
one by removing the reflected (1 - E), atmospheric (1 - tau) and IR-window
(1 - IRT) contributions, each expressed in raw units through raw(T), with
the atmospheric transmission tau of each half of the path (the window
assumed half-way) from humidity and distance:

    h2o = RH exp(1.5587 + 0.06939 t - 0.00027816 t^2 + 0.00000068455 t^3)
          (t = atmospheric temperature in C; RH in 0-1)
    tau = X exp(-sqrt(d/2) (a1 + b1 sqrt(h2o)))
          + (1 - X) exp(-sqrt(d/2) (a2 + b2 sqrt(h2o)))

then inverted: T = B / ln(R1 / (R2 (raw_obj + O)) + F).

For gas imaging the useful frame quantity is what reaches the camera, not
what a surface would be after emissivity correction: :func:`read_flir_recording`
therefore stores the *apparent* radiometric temperature (E = 1, no
atmosphere or window: T = B / ln(R1 / (R2 (raw + O)) + F)) unless asked to
apply the object parameters.
"""

from __future__ import annotations

import datetime as _dt
import mmap
import os
import struct
import warnings
from dataclasses import asdict, dataclass
from typing import BinaryIO, Dict, Iterator, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import _engine
from ..contract import FRAME_RATE_TOLERANCE, RecordingError, typical_interval
from ..errors import DataError
from ..physics.camera import Camera
from ..physics.optics import SpectralResponse
from .recording import Recording, Scene

__all__ = [
    "FlirMetadata",
    "FlirFrame",
    "FlirFile",
    "read_flir",
    "open_flir",
    "flir_temperature",
    "flir_apparent_temperature",
    "flir_raw_from_temperature",
    "read_flir_recording",
    "C2_CM_K",
]

#: Second radiation constant h c / k_B [cm K] (CODATA 2018).
C2_CM_K = 1.438776877

_FFF_MAGIC = (b"FFF\x00",)
_REC_RAW, _REC_CAMERA = 0x01, 0x20


class FlirFormatError(DataError):
    """A FLIR file that cannot be read (names the file, offset and problem)."""


@dataclass(frozen=True)
class FlirMetadata:
    """Calibration and object parameters of one FLIR frame (CameraInfo record).

    Temperatures in K, distances in m, relative humidity as a fraction 0-1.
    """

    width: int
    height: int
    emissivity: float
    object_distance_m: float
    reflected_temperature_K: float
    atmospheric_temperature_K: float
    ir_window_temperature_K: float
    ir_window_transmission: float
    relative_humidity: float
    planck_r1: float
    planck_b: float
    planck_f: float
    planck_o: float
    planck_r2: float
    atmospheric_trans_alpha1: float
    atmospheric_trans_alpha2: float
    atmospheric_trans_beta1: float
    atmospheric_trans_beta2: float
    atmospheric_trans_x: float
    camera_temperature_range_max_K: float
    camera_temperature_range_min_K: float
    camera_model: str
    camera_part_number: str
    camera_serial_number: str
    camera_software: str
    lens_model: str
    lens_part_number: str
    lens_serial_number: str
    filter_model: str
    field_of_view_deg: float
    focus_distance_m: float
    frame_rate_hz: int
    raw_value_range_min: int
    raw_value_range_max: int
    raw_value_median: int
    raw_value_range: int
    #: Capture time as Unix seconds (UTC), with the camera's milliseconds.
    timestamp_s: float
    #: The camera's local time zone offset from UTC, minutes.
    utc_offset_min: int
    #: Raw image storage: "raw-le", "raw-be", "png" or "jpegls".
    raw_format: str = "raw-le"
    #: NEAR of the JPEG-LS coding (0 = lossless; each count is within +-NEAR
    #: of the camera's), or None when the counts are not JPEG-LS coded.
    jpegls_near: Optional[int] = None

    @property
    def effective_wavenumber_cm1(self) -> float:
        """B / c2: the wavenumber of the one-line Planck law the camera was
        calibrated with [cm-1] (ExifTool's PeakSpectralSensitivity is its
        inverse in um)."""
        return self.planck_b / C2_CM_K

    @property
    def datetime(self) -> _dt.datetime:
        """Capture time in the camera's local time zone (aware datetime)."""
        tz = _dt.timezone(_dt.timedelta(minutes=self.utc_offset_min))
        return _dt.datetime.fromtimestamp(self.timestamp_s, tz)

    def as_dict(self) -> dict:
        d = asdict(self)
        d["effective_wavenumber_cm1"] = self.effective_wavenumber_cm1
        d["datetime"] = self.datetime.isoformat(timespec="milliseconds")
        return d


@dataclass
class FlirFrame:
    """One frame: raw counts (H, W) uint16 and its metadata."""

    raw: np.ndarray
    metadata: FlirMetadata

    def temperature(self, **overrides) -> np.ndarray:
        """Object temperature [K] with the frame's parameters (see
        :func:`flir_temperature`; keyword arguments override them)."""
        return flir_temperature(self.raw, self.metadata, **overrides)

    def apparent_temperature(self) -> np.ndarray:
        """Apparent (E = 1, tau = 1) radiometric temperature [K]."""
        return flir_apparent_temperature(self.raw, self.metadata)


# --------------------------------------------------------------------------- parsing


def _cstr(b: bytes) -> str:
    return b.split(b"\x00", 1)[0].decode("latin-1").strip()


class _Block:
    """An FFF block: its records (type -> (offset, length) absolute in buf)."""

    def __init__(self, buf, start: int, path: str):
        if start + 0x40 > len(buf) or bytes(buf[start : start + 4]) not in _FFF_MAGIC:
            raise FlirFormatError(f"{path}: no FFF header at byte {start}")
        hdr = bytes(buf[start : start + 0x40])
        for order in ("<", ">"):
            version, dir_off, n = struct.unpack(order + "III", hdr[0x14:0x20])
            if 100 <= version < 200:
                break
        else:
            raise FlirFormatError(
                f"{path}: FFF block at byte {start} has an unknown version "
                "(expected 100-199 in either byte order)"
            )
        if n > 10000 or start + dir_off + 32 * n > len(buf):
            raise FlirFormatError(
                f"{path}: FFF block at byte {start}: record directory "
                f"({n} entries at +{dir_off}) is beyond the end of the file"
            )
        self.start = start
        self.records: Dict[int, Tuple[int, int, int]] = {}  # type -> (offset, length, subtype)
        end = start + dir_off + 32 * n
        for i in range(n):
            e = start + dir_off + 32 * i
            rtype, sub, _ver, _idx, off, length = struct.unpack(
                order + "HHIIII", bytes(buf[e : e + 20])
            )
            if rtype == 0:
                continue
            a = start + off
            if a >= len(buf):
                raise FlirFormatError(
                    f"{path}: FFF block at byte {start}: record type "
                    f"0x{rtype:02x} starts beyond the end of the file"
                )
            # A record cut by the end of the file keeps what is there: a RawData
            # record is then checked by its decoder (the last .csq frame of a
            # truncated file often lacks only the padding after its EOI).
            length = min(length, len(buf) - a)
            self.records.setdefault(rtype, (a, length, sub))
            end = max(end, a + length)
        self.end = end


def _camera_info(buf, off: int, length: int, path: str) -> dict:
    rec = bytes(buf[off : off + length])
    if len(rec) < 0x468:
        # Older cameras write a shorter record; pad so missing fields read 0.
        rec = rec + b"\x00" * (0x468 - len(rec))
    order = "<" if struct.unpack("<H", rec[0:2])[0] < 0x100 else ">"

    def f32(o):
        return float(struct.unpack(order + "f", rec[o : o + 4])[0])

    def u16(o):
        return int(struct.unpack(order + "H", rec[o : o + 2])[0])

    rh = f32(0x3C)
    tm, ss, tz = struct.unpack(order + "IIh", rec[0x384:0x38E])
    return dict(
        emissivity=f32(0x20),
        object_distance_m=f32(0x24),
        reflected_temperature_K=f32(0x28),
        atmospheric_temperature_K=f32(0x2C),
        ir_window_temperature_K=f32(0x30),
        ir_window_transmission=f32(0x34),
        relative_humidity=rh / 100.0 if rh > 2.0 else rh,  # some files store percent
        planck_r1=f32(0x58),
        planck_b=f32(0x5C),
        planck_f=f32(0x60),
        atmospheric_trans_alpha1=f32(0x70),
        atmospheric_trans_alpha2=f32(0x74),
        atmospheric_trans_beta1=f32(0x78),
        atmospheric_trans_beta2=f32(0x7C),
        atmospheric_trans_x=f32(0x80),
        camera_temperature_range_max_K=f32(0x90),
        camera_temperature_range_min_K=f32(0x94),
        camera_model=_cstr(rec[0xD4:0xF4]),
        camera_part_number=_cstr(rec[0xF4:0x104]),
        camera_serial_number=_cstr(rec[0x104:0x114]),
        camera_software=_cstr(rec[0x114:0x124]),
        lens_model=_cstr(rec[0x170:0x190]),
        lens_part_number=_cstr(rec[0x190:0x1A0]),
        lens_serial_number=_cstr(rec[0x1A0:0x1B0]),
        filter_model=_cstr(rec[0x1EC:0x1FC]),
        field_of_view_deg=f32(0x1B4),
        planck_o=float(struct.unpack(order + "i", rec[0x308:0x30C])[0]),
        planck_r2=f32(0x30C),
        raw_value_range_min=u16(0x310),
        raw_value_range_max=u16(0x312),
        raw_value_median=u16(0x338),
        raw_value_range=u16(0x33C),
        timestamp_s=tm + (ss & 0xFFFF) / 1000.0,
        utc_offset_min=-int(tz),
        focus_distance_m=f32(0x45C),
        frame_rate_hz=u16(0x464),
    )


#: Deflate's largest compression ratio (~1032:1) with a margin: a PNG that
#: declares more pixel bytes than this times its own size is forged.
_PNG_MAX_RATIO = 1100


def _check_png(png: bytes, w: int, h: int, where: str) -> None:
    """Checks a RawData PNG before decoding: a 16-bit grey image of the
    record's size, chunks that fit in the bytes there are, and no more pixel
    bytes than its compressed data can hold. (Forged chunk lengths made the
    decoder allocate and fill ~1.8 GB for 1.6 kB of input: `make fuzz`.)"""
    if len(png) < 33 or png[12:16] != b"IHDR":
        raise FlirFormatError(f"{where} has no PNG image header")
    pw, ph = struct.unpack(">II", png[16:24])
    depth, colour = png[24], png[25]
    if depth != 16 or colour != 0:
        raise FlirFormatError(
            f"{where} is not a 16-bit grey image (bit depth {depth}, colour type {colour})"
        )
    if (w, h) != (0, 0) and (pw, ph) != (w, h):
        raise FlirFormatError(f"{where} is {pw}x{ph}, but its record says {w}x{h}")
    pos, idat = 8, 0
    while pos + 12 <= len(png):
        n = struct.unpack(">I", png[pos : pos + 4])[0]
        kind = png[pos + 4 : pos + 8]
        if pos + 12 + n > len(png):
            raise FlirFormatError(
                f"{where}: chunk {kind!r} at byte {pos} declares {n} bytes, "
                f"{len(png) - pos - 12} remain: the file is damaged"
            )
        idat += n if kind == b"IDAT" else 0
        pos += 12 + n
        if kind == b"IEND":
            break
    if pw == 0 or ph == 0 or idat == 0 or 2 * pw * ph > _PNG_MAX_RATIO * idat:
        raise FlirFormatError(
            f"{where} declares {pw}x{ph} pixels in {idat} bytes of image data: the file is damaged"
        )


def _raw_image(buf, off: int, length: int, path: str) -> Tuple[np.ndarray, str, Optional[int]]:
    rec = bytes(buf[off : off + 32])
    if len(rec) < 32:
        raise FlirFormatError(f"{path}: RawData record at byte {off} is shorter than its header")
    order = "<" if struct.unpack("<H", rec[0:2])[0] < 0x100 else ">"
    w, h = struct.unpack(order + "HH", rec[2:6])
    data = buf[off + 32 : off + length]
    head = bytes(data[:8])
    if head.startswith(b"\x89PNG\r\n\x1a\n"):
        _check_png(bytes(data), w, h, f"{path}: RawData PNG at byte {off + 32}")
        import cv2

        try:
            img = cv2.imdecode(np.frombuffer(bytes(data), np.uint8), cv2.IMREAD_UNCHANGED)
        except cv2.error:
            img = None
        if img is None or img.dtype != np.uint16:
            raise FlirFormatError(f"{path}: RawData PNG at byte {off + 32} is not a 16-bit image")
        # FLIR writes these PNGs with the 16-bit words byte-swapped (ExifTool's note).
        return img.byteswap(), "png", None
    if head.startswith(b"\xff\xd8"):
        try:
            samples, info = _engine.decode_jpegls(data)
        except ValueError as e:  # the decoder's own check of the stream
            raise FlirFormatError(f"{path}: RawData JPEG-LS at byte {off + 32}: {e}") from None
        if samples.shape[0] != 1:
            raise FlirFormatError(
                f"{path}: RawData JPEG-LS at byte {off + 32} has "
                f"{samples.shape[0]} components, expected 1"
            )
        return samples[0].astype(np.uint16, copy=False), "jpegls", int(info["near"])
    if len(data) < 2 * w * h or w == 0 or h == 0:
        raise FlirFormatError(
            f"{path}: RawData at byte {off}: {len(data)} bytes for a {w}x{h} 16-bit image"
        )
    img = np.frombuffer(data, dtype="<u2" if order == "<" else ">u2", count=w * h).reshape(h, w)
    return img.astype(np.uint16), "raw-le" if order == "<" else "raw-be", None


def _jpeg_fff(buf, path: str) -> bytes:
    """Join the FLIR APP1 segments of a radiometric JPEG into one FFF block."""
    pos, parts = 2, {}
    n = len(buf)
    while pos + 4 <= n:
        if buf[pos] != 0xFF:
            raise FlirFormatError(f"{path}: corrupt JPEG (no marker at byte {pos})")
        marker = buf[pos + 1]
        if marker in (0xD9, 0xDA):  # end of image / start of scan: no more APPn
            break
        if marker == 0xFF:
            pos += 1
            continue
        seg_len = struct.unpack(">H", bytes(buf[pos + 2 : pos + 4]))[0]
        payload = buf[pos + 4 : pos + 2 + seg_len]
        if marker == 0xE1 and bytes(payload[:5]) == b"FLIR\x00":
            if len(payload) < 8:
                raise FlirFormatError(
                    f"{path}: corrupt JPEG (a FLIR APP1 segment at byte {pos} "
                    "is shorter than its header)"
                )
            parts[payload[6]] = bytes(payload[8:])
        pos += 2 + seg_len
    if not parts:
        raise FlirFormatError(
            f"{path}: a JPEG without FLIR radiometric data (no APP1 'FLIR' "
            "segments): it is a plain picture, not a radiometric image"
        )
    return b"".join(parts[k] for k in sorted(parts))


class FlirFile:
    """A FLIR radiometric file opened for reading frame by frame.

    Use :func:`open_flir` (or :func:`read_flir`, which reads every frame).
    Frames are indexed on open (headers only); each is read and decoded
    when asked for.
    """

    def __init__(self, path: Union[str, os.PathLike]):
        self.path = os.fspath(path)
        if not os.path.isfile(self.path):
            raise FileNotFoundError(f"{self.path}: no such file")
        if os.path.getsize(self.path) < 4:
            raise FlirFormatError(f"{self.path}: file too small to be a FLIR file")
        fh = open(self.path, "rb")  # kept open for the map; close() closes it  # noqa: SIM115
        self._fh: Optional[BinaryIO] = fh
        self._map: Optional[mmap.mmap] = mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)
        try:
            self._index()
        except BaseException:
            self.close()
            raise

    def _index(self) -> None:
        assert self._map is not None  # called by __init__ on the fresh map
        self._buf: Union[mmap.mmap, bytes] = self._map
        magic = bytes(self._map[:4])
        if magic[:2] == b"\xff\xd8":
            self.kind = "jpeg"
            self._buf = _jpeg_fff(self._map, self.path)
        elif magic == b"AFF\x00":
            raise FlirFormatError(
                f"{self.path}: an AFF-format FLIR sequence; only FFF-based "
                ".seq/.csq/.fff files are supported (export it to .seq or "
                ".csq with FLIR's software)"
            )
        elif magic in _FFF_MAGIC:
            self.kind = {".csq": "csq", ".seq": "seq"}.get(
                os.path.splitext(self.path)[1].lower(), "fff"
            )
        else:
            raise FlirFormatError(
                f"{self.path}: not a FLIR radiometric file (starts with "
                f"{magic!r}; expected 'FFF\\0' for .seq/.csq/.fff or a JPEG)"
            )
        self._blocks: List[_Block] = []
        #: Frames skipped because their header is damaged: one message each
        #: (frame index in the file's order, byte range, what was found).
        self.damaged: List[str] = []
        pos = 0
        while pos + 0x40 <= len(self._buf):
            if bytes(self._buf[pos : pos + 4]) not in _FFF_MAGIC:
                nxt = self._find_next(pos)
                self._note_skipped(pos, len(self._buf) if nxt is None else nxt)
                if nxt is None:
                    break
                pos = nxt
            block = _Block(self._buf, pos, self.path)
            if _REC_RAW in block.records:
                self._blocks.append(block)
            # At least past this block's header: a forged directory (offset 0,
            # no entries) must not hold the scan in place.
            pos = max(block.end, pos + 0x40)
        if not self._blocks:
            raise FlirFormatError(f"{self.path}: no frame (no FFF block with a RawData record)")

    def _note_skipped(self, start: int, stop: int) -> None:
        """Bytes [start, stop) that hold no FFF block: padding between
        blocks (a few bytes, or one repeated byte) is normal; more than a
        block header's worth of other bytes is a frame whose header is damaged."""
        gap = bytes(self._buf[start : min(stop, start + (1 << 16))])
        if stop - start <= 0x40 or len(set(gap)) <= 1:
            return
        frame = len(self._blocks)
        self.damaged.append(
            f"{self.path}: frame {frame} (bytes {start}-{stop}, {stop - start} bytes) "
            f"skipped: no FFF frame header there (it starts with {gap[:4]!r}, expected "
            "'FFF\\0'); the file is damaged and this frame is left out"
        )

    def _find_next(self, pos: int) -> Optional[int]:
        """Next FFF header at or after pos that parses (padding between blocks)."""
        while True:
            i = self._buf.find(b"FFF\x00", pos)
            if i < 0:
                return None
            try:
                _Block(self._buf, i, self.path)
                return i
            except FlirFormatError:
                pos = i + 1

    def __len__(self) -> int:
        return len(self._blocks)

    @property
    def n_frames(self) -> int:
        return len(self._blocks)

    def metadata(self, index: int) -> FlirMetadata:
        """Metadata of frame ``index`` (reads only its headers)."""
        return self._read(index, with_raw=False)[1]

    def frame(self, index: int) -> FlirFrame:
        """Frame ``index``: raw counts (H, W) uint16, bit-exact, and metadata."""
        raw, meta = self._read(index, with_raw=True)
        assert raw is not None  # with_raw=True decodes the image
        return FlirFrame(raw, meta)

    def __getitem__(self, index: int) -> FlirFrame:
        return self.frame(index)

    def __iter__(self) -> Iterator[FlirFrame]:
        for i in range(len(self)):
            yield self.frame(i)

    def _read(self, index: int, with_raw: bool) -> Tuple[Optional[np.ndarray], FlirMetadata]:
        """Frame ``index``'s raw counts (None without ``with_raw``) and metadata."""
        n = len(self._blocks)
        i = index + n if index < 0 else index
        if not 0 <= i < n:
            raise IndexError(f"{self.path}: frame {index} is outside 0..{n - 1}")
        block = self._blocks[i]
        if _REC_CAMERA not in block.records:
            raise FlirFormatError(
                f"{self.path}: frame {i} (FFF block at byte {block.start}) "
                "has no CameraInfo record: no calibration constants"
            )
        off, length, _ = block.records[_REC_CAMERA]
        info = _camera_info(self._buf, off, length, self.path)
        roff, rlen, _ = block.records[_REC_RAW]
        hdr = bytes(self._buf[roff : roff + 32])
        if len(hdr) < 32:
            raise FlirFormatError(
                f"{self.path}: frame {i}: RawData record at byte {roff} is "
                "shorter than its header (the file is truncated)"
            )
        order = "<" if struct.unpack("<H", hdr[0:2])[0] < 0x100 else ">"
        w, h = struct.unpack(order + "HH", hdr[2:6])
        raw, fmt, near = None, None, None
        if with_raw:
            raw, fmt, near = _raw_image(self._buf, roff, rlen, self.path)
            h, w = raw.shape
        else:
            head = bytes(self._buf[roff + 32 : roff + 40])
            fmt = (
                "png"
                if head.startswith(b"\x89PNG")
                else "jpegls"
                if head.startswith(b"\xff\xd8")
                else "raw-le"
                if order == "<"
                else "raw-be"
            )
        meta = FlirMetadata(width=int(w), height=int(h), raw_format=fmt, jpegls_near=near, **info)
        return raw, meta

    def close(self) -> None:
        self._buf = b""
        m, self._map = getattr(self, "_map", None), None
        if m is not None:
            m.close()
        fh, self._fh = getattr(self, "_fh", None), None
        if fh is not None:
            fh.close()

    def __enter__(self) -> FlirFile:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"FlirFile({self.path!r}, {self.kind}, {len(self)} frames)"


def open_flir(path: Union[str, os.PathLike]) -> FlirFile:
    """Open a FLIR .seq, .csq, .fff or radiometric .jpg for frame-by-frame reading."""
    return FlirFile(path)


def read_flir(path: Union[str, os.PathLike]) -> List[FlirFrame]:
    """Read every frame of a FLIR radiometric file.

    Returns a list of :class:`FlirFrame`: ``raw`` (H, W) uint16 counts exactly
    as stored (JPEG-LS frames decoded bit-exactly) and ``metadata``
    (:class:`FlirMetadata`: Planck constants R1, R2, B, F, O, emissivity,
    object distance, reflected/atmospheric/window temperatures, window
    transmission, humidity, atmospheric constants, camera/lens names, field
    of view, time stamp). For long videos use :func:`open_flir`.
    """
    with FlirFile(path) as f:
        return list(f)


# --------------------------------------------------------------------------- counts <-> K


def _raw_of(t_K, m: FlirMetadata):
    """Counts a blackbody at t_K gives: R1 / (R2 (exp(B/T) - F)) - O."""
    return (
        m.planck_r1 / (m.planck_r2 * (np.exp(m.planck_b / np.asarray(t_K, float)) - m.planck_f))
        - m.planck_o
    )


def _counts_to_kelvin(raw_obj, m: FlirMetadata):
    with np.errstate(invalid="ignore", divide="ignore"):
        arg = m.planck_r1 / (m.planck_r2 * (np.asarray(raw_obj, float) + m.planck_o)) + m.planck_f
        t = m.planck_b / np.log(arg)
    return np.where((arg > 1.0) & np.isfinite(t), t, np.nan)


def _object_terms(
    m: FlirMetadata,
    emissivity,
    object_distance_m,
    reflected_temperature_K,
    atmospheric_temperature_K,
    ir_window_temperature_K,
    ir_window_transmission,
    relative_humidity,
):
    e = m.emissivity if emissivity is None else float(emissivity)
    d = m.object_distance_m if object_distance_m is None else float(object_distance_m)
    t_refl = (
        m.reflected_temperature_K
        if reflected_temperature_K is None
        else float(reflected_temperature_K)
    )
    t_atm = (
        m.atmospheric_temperature_K
        if atmospheric_temperature_K is None
        else float(atmospheric_temperature_K)
    )
    t_win = (
        m.ir_window_temperature_K
        if ir_window_temperature_K is None
        else float(ir_window_temperature_K)
    )
    irt = (
        m.ir_window_transmission
        if ir_window_transmission is None
        else float(ir_window_transmission)
    )
    rh = m.relative_humidity if relative_humidity is None else float(relative_humidity)
    for name, v, lo, hi in (
        ("emissivity", e, 1e-3, 1.0),
        ("object_distance_m", d, 0.0, 1e5),
        ("ir_window_transmission", irt, 1e-3, 1.0),
        ("relative_humidity", rh, 0.0, 1.0),
    ):
        if not (np.isfinite(v) and lo <= v <= hi):
            raise ValueError(f"{name} must be in [{lo:g}, {hi:g}]; got {v!r}")
    for name, v in (
        ("reflected_temperature_K", t_refl),
        ("atmospheric_temperature_K", t_atm),
        ("ir_window_temperature_K", t_win),
    ):
        if not (np.isfinite(v) and v > 0):
            raise ValueError(f"{name} must be > 0 K; got {v!r}")
    tc = t_atm - 273.15
    h2o = rh * np.exp(1.5587 + 0.06939 * tc - 0.00027816 * tc**2 + 0.00000068455 * tc**3)
    half = np.sqrt(d / 2.0)
    x = m.atmospheric_trans_x
    tau = x * np.exp(
        -half * (m.atmospheric_trans_alpha1 + m.atmospheric_trans_beta1 * np.sqrt(h2o))
    ) + (1 - x) * np.exp(
        -half * (m.atmospheric_trans_alpha2 + m.atmospheric_trans_beta2 * np.sqrt(h2o))
    )
    raw_refl, raw_atm, raw_win = _raw_of(t_refl, m), _raw_of(t_atm, m), _raw_of(t_win, m)
    gain = 1.0 / (e * tau * irt * tau)  # object signal per measured count
    offset = (
        (1 - tau) / (e * tau) * raw_atm  # atmosphere, object side
        + (1 - tau) / (e * tau * irt * tau) * raw_atm  # atmosphere, camera side
        + (1 - irt) / (e * tau * irt) * raw_win  # window emission
        + (1 - e) / e * raw_refl
    )  # reflected surroundings
    return gain, offset


def flir_temperature(
    raw,
    metadata: FlirMetadata,
    *,
    emissivity: Optional[float] = None,
    object_distance_m: Optional[float] = None,
    reflected_temperature_K: Optional[float] = None,
    atmospheric_temperature_K: Optional[float] = None,
    ir_window_temperature_K: Optional[float] = None,
    ir_window_transmission: Optional[float] = None,
    relative_humidity: Optional[float] = None,
) -> np.ndarray:
    """Object temperature [K] from raw counts, FLIR's conversion.

    Uses the frame's Planck constants and object parameters; any keyword
    overrides the stored value (temperatures in K, distance in m, humidity
    as a fraction 0-1). Equations in the module docstring (as Thermimage's
    ``raw2temp``, whose results it reproduces). Counts outside the
    calibration (no real solution) give NaN.
    """
    gain, offset = _object_terms(
        metadata,
        emissivity,
        object_distance_m,
        reflected_temperature_K,
        atmospheric_temperature_K,
        ir_window_temperature_K,
        ir_window_transmission,
        relative_humidity,
    )
    return _counts_to_kelvin(np.asarray(raw, float) * gain - offset, metadata)


def flir_apparent_temperature(raw, metadata: FlirMetadata) -> np.ndarray:
    """Apparent radiometric temperature [K]: the blackbody temperature that
    would give these counts with no emissivity, atmosphere or window
    correction, T = B / ln(R1 / (R2 (raw + O)) + F). NaN outside the calibration."""
    return _counts_to_kelvin(raw, metadata)


def flir_raw_from_temperature(temperature_K, metadata: FlirMetadata, **overrides) -> np.ndarray:
    """Inverse of :func:`flir_temperature` (Thermimage's ``temp2raw``): the
    counts an object at ``temperature_K`` gives with these parameters."""
    gain, offset = _object_terms(
        metadata,
        **{
            k: overrides.get(k)
            for k in (
                "emissivity",
                "object_distance_m",
                "reflected_temperature_K",
                "atmospheric_temperature_K",
                "ir_window_temperature_K",
                "ir_window_transmission",
                "relative_humidity",
            )
        },
    )
    return (_raw_of(temperature_K, metadata) + offset) / gain


# --------------------------------------------------------------------------- -> Recording


def _resolve_channel(channel, path: str) -> SpectralResponse:
    if channel is None:
        raise RecordingError(
            path,
            "channel",
            "a FLIR file stores raw counts and a one-line Planck calibration, not the camera's "
            "spectral response, which converting temperature to band radiance needs",
            "pass channel=qogi.SpectralResponse(...) or channel='response.csv' (two columns: "
            "wavenumber_cm1 or wavelength_um, response) describing the camera's band "
            "(filter x lens x detector), e.g. 7.5-13 um for an uncooled LWIR camera",
        )
    if isinstance(channel, (str, os.PathLike)):
        channel = SpectralResponse.from_csv(channel)
    if not isinstance(channel, SpectralResponse):
        raise TypeError(
            f"channel must be a qogi.SpectralResponse or a CSV path; got {type(channel).__name__}"
        )
    return channel


def _check_band(channel: SpectralResponse, meta: FlirMetadata, path: str) -> None:
    nu_eff = meta.effective_wavenumber_cm1
    if nu_eff > 0 and abs(channel.centroid_cm1 - nu_eff) > 0.35 * nu_eff:
        warnings.warn(
            f"{path}: the channel {channel.name!r} is centred at {channel.centroid_cm1:.0f} cm-1 "
            f"({1e4 / channel.centroid_cm1:.2f} um) but the camera's calibration (Planck B = "
            f"{meta.planck_b:g} K) implies {nu_eff:.0f} cm-1 ({1e4 / nu_eff:.2f} um): check "
            "that the response belongs to this camera",
            UserWarning,
            stacklevel=3,
        )


def read_flir_recording(
    path: Union[str, os.PathLike],
    *,
    channel=None,
    pressure_Pa: Optional[float] = None,
    distance_m: Optional[float] = None,
    ambient_temperature_K: Optional[float] = None,
    ifov_rad: Optional[float] = None,
    frame_rate_hz: Optional[float] = None,
    object_parameters: bool = False,
    scene_extra: Optional[dict] = None,
    frames: Optional[Sequence[int]] = None,
) -> Recording:
    """Convert a FLIR file into a :class:`qogi.Recording` (radiometric temperature).

    Parameters
    ----------
    path : str or path
        .seq, .csq, .fff or radiometric .jpg.
    channel : SpectralResponse or str (CSV path)
        Required: the camera's spectral response. FLIR files do not carry it.
    pressure_Pa : float, Pa
        Required: ambient pressure (not stored by FLIR cameras).
    distance_m, ambient_temperature_K : float, optional
        Default: the camera's object distance and atmospheric temperature.
    ifov_rad : float, rad, optional
        Default: field of view / width (from the file).
    frame_rate_hz : float, Hz, optional
        If given, frame times are ``i / frame_rate_hz`` (overriding the time
        stamps). Otherwise the time stamps are used when they increase,
        else the camera's frame rate.
    object_parameters : bool, default False
        False: frames are the apparent radiometric temperature (E = 1, no
        atmosphere, no window): what reaches the camera, which the gas
        radiative transfer models. True: FLIR's object temperature with the
        stored emissivity, distance, humidity etc.
    scene_extra : dict, optional
        More :class:`qogi.Scene` fields (wind_speed_m_s, gas_temperature_K,
        background_temperature_K, species).
    frames : sequence of int, optional
        Frame indices to convert (default all).

    Counts outside the camera calibration become NaN invalid pixels (the
    recording then has ``nonfinite="invalid"`` and counts them).
    """
    p = os.fspath(path)
    ch = _resolve_channel(channel, p)
    if pressure_Pa is None:
        raise RecordingError(
            p,
            "pressure_Pa",
            "FLIR files do not record the ambient pressure, which the gas absorption depends on",
            "pass pressure_Pa (e.g. 101325 at sea level)",
        )
    with FlirFile(p) as f:
        idx = list(range(len(f))) if frames is None else [int(i) for i in frames]
        if not idx:
            raise ValueError("frames must name at least one frame")
        out, metas = [], []
        for i in idx:
            fr = f.frame(i)
            t = (
                flir_temperature(fr.raw, fr.metadata)
                if object_parameters
                else flir_apparent_temperature(fr.raw, fr.metadata)
            )
            out.append(t.astype(np.float32)[None])
            metas.append(fr.metadata)
    shapes = {o.shape for o in out}
    if len(shapes) != 1:
        raise RecordingError(p, "frames", f"frames have different sizes {sorted(shapes)}")
    m0 = metas[0]
    _check_band(ch, m0, p)
    stamps = np.array([m.timestamp_s for m in metas])
    if frame_rate_hz is not None:
        rate = float(frame_rate_hz)
        if not (np.isfinite(rate) and rate > 0):
            raise ValueError(f"frame_rate_hz must be > 0; got {frame_rate_hz!r}")
        times = np.arange(len(idx)) / rate
    elif len(idx) > 1 and np.all(np.diff(stamps) > 0):
        # Time stamps (1 ms resolution); the nominal rate when they agree with it.
        times = stamps - stamps[0]
        rate = 1.0 / typical_interval(times)
        if (
            m0.frame_rate_hz > 0
            and abs(rate - m0.frame_rate_hz) <= FRAME_RATE_TOLERANCE * m0.frame_rate_hz
        ):
            rate = float(m0.frame_rate_hz)
    elif m0.frame_rate_hz > 0:
        rate = float(m0.frame_rate_hz)
        times = np.arange(len(idx)) / rate
    else:
        raise RecordingError(
            p,
            "frame_rate_hz",
            "the file has neither increasing time stamps nor a frame rate",
            "pass frame_rate_hz",
        )
    if ifov_rad is None:
        if not (m0.field_of_view_deg > 0 and m0.width > 0):
            raise RecordingError(
                p,
                "ifov_rad",
                "the file has no field of view",
                "pass ifov_rad (angular size of one pixel, rad)",
            )
        ifov_rad = np.deg2rad(m0.field_of_view_deg) / m0.width
    cam_name = " ".join(s for s in (m0.camera_model, m0.lens_model) if s) or "FLIR"
    camera = Camera(cam_name, float(ifov_rad), [ch], rate)
    scene = Scene(
        distance_m=m0.object_distance_m if distance_m is None else distance_m,
        ambient_temperature_K=(
            m0.atmospheric_temperature_K if ambient_temperature_K is None else ambient_temperature_K
        ),
        pressure_Pa=pressure_Pa,
        **(scene_extra or {}),
    )
    data = np.stack(out)
    rec = Recording.from_arrays(
        data,
        times,
        quantity="radiometric_temperature",
        camera=camera,
        scene=scene,
        nonfinite="invalid",
    )
    rec.path = p
    rec.attrs.update(
        {
            "source": os.path.basename(p),
            "source_format": f"FLIR {m0.raw_format}",
            "flir_temperature": "object" if object_parameters else "apparent",
            "flir_planck_r1": m0.planck_r1,
            "flir_planck_r2": m0.planck_r2,
            "flir_planck_b": m0.planck_b,
            "flir_planck_f": m0.planck_f,
            "flir_planck_o": m0.planck_o,
        }
    )
    return rec
