"""Speed of the recording I/O: JPEG-LS decoding of FLIR .csq frames, the
temperature <-> radiance tables, and frame reads from recording files.

Each figure is printed with a baseline timed in the same run:
- JPEG-LS decode of a 1024x768 16-bit .csq frame vs zlib (stdlib, level 6)
  decompressing the same frame's counts (a lossless codec everyone has);
- BandTable conversion of a 4x256x320 frame vs the exact engine calls
  (SpectralResponse.band_radiance / radiometric_temperature);
- reading one 4x256x320 frame from an HDF5 recording vs copying it in memory,
  and the open-time NaN scan vs reading the file's bytes.

Run: .venv/bin/python benchmarks/bench_recording.py
"""

from __future__ import annotations

import os
import struct
import tempfile
import time
import zlib
from pathlib import Path

import numpy as np
from _timing import best_time

import qogi
from qogi import _engine
from qogi.physics.radiometry import BandTable

SHARED = Path(os.environ.get("QOGI_SHARED_DIR", Path(__file__).resolve().parents[2] / "shared"))


def best(fn, repeat=5):
    return best_time(fn, repeat)


def csq_frame():
    data = (SHARED / "samples" / "flir" / "SampleCSQ.csq").read_bytes()
    dir_off, n = struct.unpack("<II", data[0x18:0x20])
    for i in range(n):
        rtype, _, _, _, off, length = struct.unpack(
            "<HHIIII", data[dir_off + 32 * i : dir_off + 32 * i + 20]
        )
        if rtype == 1:
            return data[off + 32 : off + length]
    raise RuntimeError("no RawData record")


def main():
    code = csq_frame()
    img, _ = _engine.decode_jpegls(code)
    packed = zlib.compress(img.tobytes(), 6)
    t_jls = best(lambda: _engine.decode_jpegls(code), 10)
    t_zlib = best(lambda: zlib.decompress(packed), 10)
    print(
        f"JPEG-LS decode 1024x768x16 bit (.csq frame): {t_jls * 1e3:.1f} ms; "
        f"zlib.decompress of the same counts: {t_zlib * 1e3:.1f} ms; ratio {t_jls / t_zlib:.2f}"
    )

    chs = [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], "3.2-3.4 um"),
        qogi.SpectralResponse([1852.0, 6667.0], [1.0, 1.0], "InSb"),
        qogi.SpectralResponse([2500.0, 2700.0], [1.0, 1.0], "CO2 band"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], "window"),
    ]
    t0 = time.perf_counter()
    tables = [BandTable(c) for c in chs]
    t_build = time.perf_counter() - t0
    frame = np.random.default_rng(0).uniform(260.0, 340.0, (4, 256, 320)).astype(np.float32)
    lum = np.stack([tb.radiance(frame[k]) for k, tb in enumerate(tables)])
    t_tab = best(lambda: [tb.radiance(frame[k]) for k, tb in enumerate(tables)])
    t_inv = best(lambda: [tb.temperature(lum[k]) for k, tb in enumerate(tables)])
    sub = frame[:, :32, :]  # the exact calls are slow: time 1/8 of the frame, scale up
    t_exact = (
        best(lambda: [c.band_radiance(sub[k].astype(np.float64)) for k, c in enumerate(chs)], 2) * 8
    )
    t_exact_inv = (
        best(
            lambda: [
                c.radiometric_temperature(lum[k, :4].astype(np.float64)) for k, c in enumerate(chs)
            ],
            1,
        )
        * 64
    )
    print(f"tables for 4 channels built in {t_build:.2f} s (once per channel, cached)")
    nu = np.arange(2850.0, 3200.0, 1.0)
    rng = np.random.default_rng(1)
    t_test = np.concatenate([rng.uniform(150.0, 1500.0, 20000), np.linspace(150.0, 1500.0, 3001)])
    for c in [
        chs[0],
        qogi.SpectralResponse(nu, np.exp(-(((nu - 3030.0) / 70.0) ** 8)), "smooth CH4"),
        chs[1],
        qogi.SpectralResponse.from_wavelength_um([7.5, 13.0], [1.0, 1.0], "LWIR"),
    ]:
        tb = BandTable(c)
        exact = c.band_radiance(t_test)
        print(
            f"  table error vs exact engine, {c.name:>11}, 150-1500 K: max |dL/L| "
            f"{np.max(np.abs(tb.radiance(t_test) / exact - 1)):.1e}, max |dT| "
            f"{np.max(np.abs(tb.temperature(exact) - t_test)):.1e} K"
        )
    print(
        f"T -> L, 4x256x320 frame: tables {t_tab * 1e3:.1f} ms; "
        f"exact engine {t_exact * 1e3:.0f} ms; speed-up {t_exact / t_tab:.0f}x"
    )
    print(
        f"L -> T, 4x256x320 frame: tables {t_inv * 1e3:.1f} ms; exact engine "
        f"{t_exact_inv * 1e3:.0f} ms; speed-up {t_exact_inv / t_inv:.0f}x"
    )

    n = 200
    with tempfile.TemporaryDirectory() as d:
        for comp in (None, "lzf"):
            p = Path(d) / f"bench_{comp}.h5"
            cam = qogi.Camera("bench", 1e-3, chs, 100.0)
            sc = qogi.Scene(10.0, 293.15, 101325.0)
            with qogi.RecordingWriter(
                p,
                quantity="radiometric_temperature",
                camera=cam,
                scene=sc,
                frame_shape=(4, 256, 320),
                compression=comp,
                expected_frames=n,
            ) as w:
                for i in range(n):
                    w.append(frame + np.float32(0.01 * i), i / 100.0)
            size_mb = p.stat().st_size / 1e6
            t_open = best(lambda p=p: qogi.open_recording(p).close(), 2)
            t_bytes = best(p.read_bytes, 2)
            rec = qogi.open_recording(p, check_frames=False)
            idx = iter(np.random.default_rng(1).integers(0, n, 1000))
            t_read = best(lambda rec=rec, idx=idx: rec.frame(int(next(idx))), 20)
            t_copy = best(frame.copy, 20)
            rec.close()
            print(
                f"recording {n} frames 4x256x320 ({comp or 'uncompressed'}, {size_mb:.0f} MB): "
                f"open with NaN scan {t_open:.2f} s vs reading its bytes {t_bytes:.2f} s "
                f"(ratio {t_open / t_bytes:.1f}); one random frame {t_read * 1e3:.2f} ms vs "
                f"in-memory copy {t_copy * 1e3:.2f} ms (ratio {t_read / t_copy:.1f})"
            )


if __name__ == "__main__":
    main()
