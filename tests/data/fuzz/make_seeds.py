"""Writes the fuzzers' seed corpus: small valid files of every layout the FLIR
reader (qogi.io.flir) and the recording reader (qogi.open_recording) accept.

    python tests/data/fuzz/make_seeds.py      # rewrites tests/data/fuzz/seeds/

FLIR files are built from the layout qogi.io.flir parses (an FFF header, a
record directory, a CameraInfo record with the Planck constants and a RawData
record: raw 16-bit little- or big-endian, 16-bit PNG, or JPEG-LS from
tests/data/jpegls), as a single .fff, a 3-frame .seq, a .csq and a
radiometric .jpg (the FFF block split over APP1 'FLIR' segments). Recordings
are written by qogi.write_recording. Everything is deterministic.
"""

from __future__ import annotations

import pathlib
import struct
import sys

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
SEEDS = HERE / "seeds"
JPEGLS = HERE.parent / "jpegls"

REC_RAW, REC_CAMERA = 0x01, 0x20


def camera_info(order: str = "<") -> bytes:
    """A CameraInfo record (0x468 bytes) with a GF320-like Planck calibration."""
    rec = bytearray(0x468)

    def f32(off, v):
        rec[off : off + 4] = struct.pack(order + "f", v)

    struct.pack_into(order + "H", rec, 0, 2)  # a small first word: the byte order
    for off, v in (
        (0x20, 0.95),
        (0x24, 1.5),
        (0x28, 293.15),
        (0x2C, 293.15),
        (0x30, 293.15),
        (0x34, 1.0),
        (0x3C, 0.5),
        (0x58, 21106.77),
        (0x5C, 1501.0),
        (0x60, 1.0),
        (0x70, 0.006569),
        (0x74, 0.01262),
        (0x78, -0.002276),
        (0x7C, -0.00667),
        (0x80, 1.9),
        (0x90, 423.15),
        (0x94, 253.15),
        (0x1B4, 24.0),
        (0x30C, 0.012545258),
        (0x45C, 1.5),
    ):
        f32(off, v)
    rec[0xD4 : 0xD4 + 9] = b"FUZZ-CAM\x00"
    struct.pack_into(order + "i", rec, 0x308, -7340)
    struct.pack_into(order + "HH", rec, 0x310, 1000, 30000)
    struct.pack_into(order + "IIh", rec, 0x384, 1_600_000_000, 250, 0)
    struct.pack_into(order + "H", rec, 0x464, 30)
    return bytes(rec)


def raw_record(img: np.ndarray, kind: str, order: str = "<") -> bytes:
    h, w = img.shape
    hdr = bytearray(32)
    struct.pack_into(order + "HHH", hdr, 0, 2, w, h)
    if kind == "raw":
        return bytes(hdr) + img.astype(order + "u2").tobytes()
    if kind == "png":
        import cv2

        ok, png = cv2.imencode(".png", img.astype(np.uint16).byteswap())
        assert ok
        return bytes(hdr) + png.tobytes()
    if kind == "jpegls":
        return bytes(hdr) + (JPEGLS / "gray16_sensor.jls").read_bytes()
    raise ValueError(kind)


def fff_block(img: np.ndarray, kind: str = "raw", order: str = "<") -> bytes:
    """One FFF block: header, a 2-entry record directory, CameraInfo, RawData."""
    cam, raw = camera_info(order), raw_record(img, kind, order)
    dir_off = 0x40
    first = dir_off + 2 * 32
    hdr = bytearray(0x40)
    hdr[0:4] = b"FFF\x00"
    hdr[4 : 4 + 8] = b"FUZZ\x00\x00\x00\x00"
    struct.pack_into(order + "III", hdr, 0x14, 100, dir_off, 2)
    entries = b""
    for rtype, off, length in (
        (REC_CAMERA, first, len(cam)),
        (REC_RAW, first + len(cam), len(raw)),
    ):
        e = bytearray(32)
        struct.pack_into(order + "HHIIII", e, 0, rtype, 1, 100, 1, off, length)
        entries += bytes(e)
    return bytes(hdr) + entries + cam + raw


def radiometric_jpeg(fff: bytes) -> bytes:
    """A JPEG whose APP1 'FLIR' segments carry ``fff`` (no picture data)."""
    out = bytearray(b"\xff\xd8")
    chunks = [fff[i : i + 4000] for i in range(0, len(fff), 4000)]
    for k, c in enumerate(chunks):
        payload = b"FLIR\x00\x01" + bytes([k, len(chunks) - 1]) + c
        out += b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    out += b"\xff\xd9"
    return bytes(out)


def image(w: int = 16, h: int = 12, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return (14000 + rng.integers(0, 400, (h, w))).astype(np.uint16)


def flir_seeds() -> dict:
    jls = np.load(JPEGLS / "gray16_sensor.npy")
    return {
        "flir_raw_le.fff": fff_block(image()),
        "flir_raw_be.fff": fff_block(image(seed=1), order=">"),
        "flir_png.fff": fff_block(image(seed=2), kind="png"),
        "flir_three.seq": b"".join(fff_block(image(seed=s)) for s in range(3)),
        "flir_jpegls.csq": b"".join(
            fff_block(jls.astype(np.uint16).reshape(jls.shape[-2:]), kind="jpegls")
            for _ in range(2)
        ),
        "flir_radiometric.jpg": radiometric_jpeg(fff_block(image(seed=3))),
    }


def recording_seeds(folder: pathlib.Path) -> None:
    sys.path.insert(0, str(HERE.parents[2] / "python"))
    import qogi

    chs = [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], name="4.5-5.0 um"),
    ]
    t = np.arange(4)[:, None, None]
    temp = 285.0 + 3.0 * np.exp(
        -((np.arange(8)[None, None, :] - 4) ** 2 + (np.arange(6)[None, :, None] - 5 + t) ** 2) / 4.0
    )
    frames = np.stack([c.band_radiance(temp.ravel()).reshape(temp.shape) for c in chs], axis=1)
    cam = qogi.Camera("fuzz camera", 1e-3, chs, frame_rate_hz=10.0, netd_K=0.02)
    scene = qogi.Scene(
        distance_m=3.0, ambient_temperature_K=288.0, pressure_Pa=101325.0, species=("CH4",)
    )
    rec = qogi.Recording.from_arrays(
        frames, quantity="radiance", camera=cam, scene=scene, truth=qogi.Truth({"CH4": 1e-4})
    )
    rec.save(folder / "recording_radiance.h5")
    rec.save(folder / "recording_gzip.h5", compression="gzip")
    tempk = np.stack([temp, temp + 1.0], axis=1).astype(np.float32)
    qogi.Recording.from_arrays(
        tempk, quantity="radiometric_temperature", camera=cam, scene=scene
    ).save(folder / "recording_temperature.h5")


def main() -> None:
    SEEDS.mkdir(parents=True, exist_ok=True)
    for name, data in flir_seeds().items():
        (SEEDS / name).write_bytes(data)
    recording_seeds(SEEDS)
    for p in sorted(SEEDS.iterdir()):
        print(f"{p.stat().st_size:8d}  {p.relative_to(HERE)}")


if __name__ == "__main__":
    main()
