"""Makes the JPEG-LS reference data used by the decoder tests (run once).

The codestreams are written by CharLS (an independent, widely used JPEG-LS
codec) through `pyjpegls` and `imagecodecs`, and the expected samples are
CharLS's own decoding of them. Neither package is a dependency of qogi: they
were pip-installed into a developer's .venv only to run this script.

    .venv/bin/pip install pyjpegls imagecodecs
    .venv/bin/python tests/data/jpegls/make_reference.py

Writes, next to this script: <name>.jls (codestream), <name>.npy (expected
samples, shape (components, height, width)), manifest.txt (one line per
case: name components height width bits near ilv fnv1a64-of-samples, used
by the C++ test), and ../flir/csq_reference.json (CharLS's decoding of every
frame of the shared FLIR sample SampleCSQ.csq, as sha256 of the uint16
little-endian samples plus a few pixel values).
"""

from __future__ import annotations

import hashlib
import json
import os
import struct
from pathlib import Path

import imagecodecs
import jpeg_ls
import numpy as np

HERE = Path(__file__).resolve().parent
# The folder holding samples/flir/SampleCSQ.csq (third-party, not in the repository).
SHARED = Path(os.environ["QOGI_SHARED_DIR"])


def fnv1a64(samples: np.ndarray) -> int:
    h = 0xCBF29CE484222325
    for v in samples.astype("<u2").ravel().tobytes():
        h ^= v
        h = (h * 0x100000001B3) & 0xFFFFFFFFFFFFFFFF
    return h


def header(code: bytes):
    sof = code.find(b"\xff\xf7")
    bits, height, width, comps = struct.unpack(">BHHB", code[sof + 4 : sof + 10])
    sos = code.find(b"\xff\xda")
    ns = code[sos + 4]
    near, ilv = code[sos + 5 + 2 * ns], code[sos + 6 + 2 * ns]
    return comps, height, width, bits, near, ilv


def cases(rng: np.random.Generator):
    yy, xx = np.mgrid[0:23, 0:37]
    smooth = 60 + 2 * xx + yy + rng.integers(-3, 4, (23, 37))
    smooth[5:12, 10:30] = 77  # flat block: run mode, interruptions
    smooth[15:18, :] = 140  # whole flat lines: runs to end of line
    smooth[20, 30:] = 9  # run reaching the last column
    yield "gray8_smooth", smooth.astype(np.uint8), 0, None
    yield "gray8_random", rng.integers(0, 256, (11, 19), dtype=np.uint8), 0, None
    yield "gray8_flat", np.full((9, 300), 100, np.uint8), 0, None
    long_runs = np.full((12, 700), 50, np.uint8)
    long_runs[:, ::97] = 51  # interruptions after runs of 96 (large J)
    long_runs[6, 400:] = 200
    yield "gray8_long_runs", long_runs, 0, None
    yield "gray8_width1", rng.integers(0, 256, (20, 1), dtype=np.uint8), 0, None
    yield "gray8_height1", rng.integers(0, 256, (1, 20), dtype=np.uint8), 0, None
    yield "gray8_near2", smooth.astype(np.uint8), 2, None

    y, x = np.mgrid[0:48, 0:64]
    sensor = (
        14000
        + 8 * x
        + 3 * y
        + 900 * np.exp(-((x - 40) ** 2 + (y - 20) ** 2) / 60.0)
        + rng.normal(0, 6, (48, 64))
    )
    sensor[30:40, 5:25] = 14123  # flat patch
    sensor[44:, :] = 65535  # saturated lines
    yield "gray16_sensor", np.clip(sensor, 0, 65535).astype(np.uint16), 0, None
    yield "gray16_random", rng.integers(0, 65536, (9, 16), dtype=np.uint16), 0, None
    yield "gray16_near3", np.clip(sensor, 0, 65535).astype(np.uint16), 3, None
    g12 = (2000 + 30 * xx[:17, :33] + rng.integers(-40, 41, (17, 33))).clip(0, 4095)
    yield "gray12", g12.astype(np.uint16), 0, ("bits", 12)
    g5 = (smooth // 8).clip(0, 31)
    g5[0:3, :] = rng.integers(0, 32, (3, 37))
    yield "gray5", g5.astype(np.uint8), 0, ("bits", 5)  # MAXVAL < 128 thresholds
    yield "gray5_near1", g5.astype(np.uint8), 1, ("bits", 5)

    rgb = np.stack([smooth, 255 - smooth, (smooth // 2 + 30)], axis=-1).astype(np.uint8)
    rgb[2:4, :, 1] = rng.integers(0, 256, (2, 37))
    yield "rgb8_ilv0", rgb, 0, 0
    yield "rgb8_ilv1", rgb, 0, 1


def main() -> None:
    rng = np.random.default_rng(20240611)
    lines = []
    for name, img, near, ilv in cases(rng):
        if ilv is None:
            code = bytes(imagecodecs.jpegls_encode(img, level=near))
        elif isinstance(ilv, tuple):  # a precision P other than 8 or 16
            code = bytes(
                jpeg_ls.encode_buffer(
                    img.astype("<u2").tobytes() if img.dtype == np.uint16 else img.tobytes(),
                    img.shape[0],
                    img.shape[1],
                    1,
                    ilv[1],
                    lossy_error=near,
                )
            )
        else:  # pyjpegls wants planar input for ILV 0, pixel-interleaved for ILV 1
            src = np.ascontiguousarray(np.moveaxis(img, -1, 0)) if ilv == 0 else img
            code = bytes(jpeg_ls.encode_array(src, lossy_error=near, interleave_mode=ilv))
        decoded = np.asarray(imagecodecs.jpegls_decode(code))
        planar = decoded[None] if decoded.ndim == 2 else np.moveaxis(decoded, -1, 0)
        if near == 0:
            original = img[None] if img.ndim == 2 else np.moveaxis(img, -1, 0)
            assert np.array_equal(planar, original), name
        else:
            assert (
                np.abs(
                    planar.astype(int)
                    - (img[None] if img.ndim == 2 else np.moveaxis(img, -1, 0)).astype(int)
                ).max()
                <= near
            ), name
        comps, height, width, bits, snear, silv = header(code)
        assert (comps, height, width) == planar.shape and snear == near, name
        (HERE / f"{name}.jls").write_bytes(code)
        np.save(HERE / f"{name}.npy", np.ascontiguousarray(planar))
        lines.append(f"{name} {comps} {height} {width} {bits} {near} {silv} {fnv1a64(planar):016x}")
    (HERE / "manifest.txt").write_text(
        "# name components height width bits near ilv fnv1a64(samples as uint16 LE, planar)\n"
        + "\n".join(lines)
        + "\n"
    )

    # Every frame of the FLIR sample .csq: FFF records, RawData holds JPEG-LS.
    data = (SHARED / "samples" / "flir" / "SampleCSQ.csq").read_bytes()
    frames, pos = [], 0
    while pos + 0x40 <= len(data) and data[pos : pos + 4] == b"FFF\x00":
        dir_off, n = struct.unpack("<II", data[pos + 0x18 : pos + 0x20])
        end = pos
        for i in range(n):
            rtype, _, _, _, off, length = struct.unpack(
                "<HHIIII", data[pos + dir_off + 32 * i : pos + dir_off + 32 * i + 20]
            )
            end = max(end, pos + off + length)
            if rtype == 1:
                img = imagecodecs.jpegls_decode(data[pos + off + 32 : pos + off + length])
                frames.append(
                    {
                        "index": len(frames),
                        "shape": list(img.shape),
                        "sha256_uint16_le": hashlib.sha256(img.astype("<u2").tobytes()).hexdigest(),
                        "pixels_yx": [
                            [y, x, int(img[y, x])]
                            for y, x in [(0, 0), (0, 1023), (767, 0), (384, 512), (100, 700)]
                        ],
                        "min": int(img.min()),
                        "max": int(img.max()),
                    }
                )
        pos = end
    (HERE.parent / "flir").mkdir(exist_ok=True)
    (HERE.parent / "flir" / "csq_reference.json").write_text(
        json.dumps(
            {
                "source": "SampleCSQ.csq decoded by CharLS (imagecodecs "
                f"{imagecodecs.__version__}) via tests/data/jpegls/make_reference.py",
                "frames": frames,
            },
            indent=1,
        )
        + "\n"
    )


if __name__ == "__main__":
    main()
