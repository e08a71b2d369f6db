"""End to end: recording -> emission rate, against real time (issue 8).

Two cases, as the issue asks:

* 60 s of 15 Hz single-channel video (lab-ch4-5slpm-gf320, 900 frames of
  320x240), gas temperature ambient, the default velocimetry;
* 10 s of 100 Hz four-channel video (lab-ch4co2-90c-m150, 1000 frames of
  4 x 320x256), gas temperature inferred, the default velocimetry.

Baseline in the same run: the video's own duration (real time); a ratio
below 1 is faster than real time. Three control surfaces (4, 8, 12 cm).
The recordings are built from a shorter synthetic release looped to the
length asked for (rendering 1000 four-channel frames takes minutes and is
measured by bench_render.py); the pipeline's work does not depend on the
content's novelty. Reported: the first run in a process (the scene's
inversion table is built in it; cross-section tables come from the disk
cache), and with QOGI_BENCH_RUNS=2 also a second (tables in memory).
"""

import os
import tempfile
import time

import qogi
from qogi.io.hdf5_writer import RecordingWriter
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import truth_surfaces
from qogi.synth import render

CASES = [
    ("lab-ch4-5slpm-gf320", 60.0, 4.0, "ambient", None),
    ("lab-ch4co2-90c-m150", 10.0, 1.0, "infer", {"CH4": 0.5, "CO2": 0.5}),
]


def looped(src_path, dst_path, duration_s, start=0):
    """A recording of ``duration_s`` looping ``src_path``'s frames from frame
    ``start`` (at its frame rate); also used by bench_batch.py."""
    src = qogi.open_recording(src_path)
    rate = src.camera.frame_rate_hz
    n = int(round(duration_s * rate))
    with RecordingWriter(
        dst_path,
        quantity=src.quantity,
        camera=src.camera,
        scene=src.scene,
        frame_shape=src.shape[1:],
        truth=src.truth,
        expected_frames=n,
    ) as w:
        for i in range(n):
            w.append(src.frame((start + i) % src.n_frames), i / rate)
    src.close()
    return dst_path


def main():
    scale = float(os.environ.get("QOGI_BENCH_SCALE", "1"))
    with tempfile.TemporaryDirectory() as d:
        for preset, base_duration, source_s, gas, comp in CASES:
            duration = base_duration * scale
            t = time.perf_counter()
            src = render.synthesize(preset, os.path.join(d, "src.h5"), duration_s=source_s, seed=0)
            t_render = time.perf_counter() - t
            path = looped(src, os.path.join(d, "rec.h5"), duration)
            rec = qogi.open_recording(path)
            surf, source = truth_surfaces(
                rec, heights_m=(0.04, 0.08, 0.12), half_width_px=50 if rec.height == 256 else 40
            )
            cfg = QuantifyConfig(
                species=list(rec.scene.species),
                gas_temperature=gas,
                composition=comp,
                source=source,
            )
            times = []
            runs = ("cold", "warm")[: int(os.environ.get("QOGI_BENCH_RUNS", "1"))]
            for _run in runs:
                t = time.perf_counter()
                c = time.process_time()
                res = quantify(rec, surf, cfg)
                times.append((time.perf_counter() - t, time.process_time() - c))
            print(
                f"{preset}: {rec.n_frames} frames ({duration:g} s of {rec.n_channels}-channel "
                f"{rec.width}x{rec.height} at {rec.camera.frame_rate_hz:g} Hz), gas temperature "
                f"{gas}, {len(surf)} surfaces"
            )
            for run, (wall, cpu) in zip(runs, times):
                print(
                    f"  {run}: {wall:.1f} s wall ({cpu:.1f} s CPU) = {wall / duration:.2f}x real "
                    f"time ({'faster' if wall < duration else 'SLOWER'} than the camera)"
                )
            r = res.surfaces[len(res.surfaces) // 2].species["CH4"]
            middle = res.surfaces[len(res.surfaces) // 2].surface.name
            print(
                f"  (source rendered in {t_render:.0f} s; {middle}: "
                f"{r.mean_kg_h * 1000:.1f} g/h CH4, truth {r.truth_kg_h * 1000:.1f} g/h)"
            )
            rec.close()


if __name__ == "__main__":
    main()
