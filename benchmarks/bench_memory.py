"""Peak memory and time per frame against the recording's length (issue 16):
1, 5 and 20 minutes of 15 Hz single-channel video (lab-ch4-5slpm-gf320,
320x240), the default pipeline (inverted columns, fluid velocimetry with the
transport's flux level, three surfaces).

A 4 s release is rendered once and presented as a long recording by a
Recording whose frames are that release looped (a source object that
serves any slice; nothing is loaded up front), so the pipeline reads a long
recording block by block just as it reads an HDF5 file. Each length runs in
its own process (peak RSS, ``ru_maxrss``, is per process). Baseline in the
same run: the 1-minute case; the pipeline streams the run in blocks
(docs/pipeline_api.md), so peak RSS and time per frame should stay within
~20 % of it. The aim for embedding (issue 30): a peak of at most
:data:`AIM_MB`; each length's peak is printed against it too.

    python benchmarks/bench_memory.py            # 1, 5, 20 minutes
    python benchmarks/bench_memory.py 1 5        # chosen lengths [min]
"""

import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

PRESET = "lab-ch4-5slpm-gf320"
BASE_S = 4.0
#: Peak RSS [MB] small enough to embed (issue 30), for 15 Hz 320x240 frames.
AIM_MB = 300.0


class Looped:
    """(T, C, H, W) frames: ``frames`` repeated to ``n`` frames (read-only slices)."""

    def __init__(self, frames: np.ndarray, n: int):
        self.frames, self.n = frames, n
        self.shape = (n,) + frames.shape[1:]
        self.dtype = frames.dtype

    def __getitem__(self, key):
        idx = np.arange(self.n)[key]
        return self.frames[idx % len(self.frames)]


def one(path: str, minutes: float) -> dict:
    import qogi
    from qogi.io.recording import Recording
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.pipeline.surfaces import truth_surfaces

    src = qogi.open_recording(path).load()
    rate = src.camera.frame_rate_hz
    n = int(round(minutes * 60 * rate))
    rec = Recording(
        source=Looped(src.to_array(), n),
        time_s=np.arange(n) / rate,
        quantity=src.quantity,
        camera=src.camera,
        scene=src.scene,
        truth=src.truth,
        path=f"<{minutes:g} min looped>",
        nonfinite="error",
    )
    surfaces, source = truth_surfaces(rec, heights_m=[0.04, 0.08, 0.12], half_width_px=50)
    t0 = time.perf_counter()
    res = quantify(rec, surfaces, QuantifyConfig(species=["CH4"], source=source))
    dt = time.perf_counter() - t0
    r = res.surfaces[1].species["CH4"]
    return {
        "minutes": minutes,
        "frames": n,
        "seconds": dt,
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
        "blocks": res.info.get("blocks", 1),
        "mean_kg_h": r.mean_kg_h,
    }


def main(lengths):
    from qogi.synth import render

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "base.h5")
        render.synthesize(PRESET, path, duration_s=BASE_S, seed=3)
        rows = []
        for m in lengths:
            out = subprocess.run(
                [sys.executable, __file__, "--one", path, str(m)],
                check=True,
                capture_output=True,
                text=True,
            )
            rows.append(json.loads(out.stdout.strip().splitlines()[-1]))
            print(f"  {m:g} min done", flush=True)
    base = rows[0]
    print(
        f"{'length':>8} {'frames':>7} {'blocks':>6} {'peak RSS MB':>12} {'x 1st':>6} "
        f"{'x aim':>6} {'ms/frame':>9} {'x 1st':>6} {'kg/h':>8}"
    )
    for r in rows:
        ms = 1000 * r["seconds"] / r["frames"]
        ms0 = 1000 * base["seconds"] / base["frames"]
        print(
            f"{r['minutes']:>6g} m {r['frames']:>7d} {r['blocks']:>6d} {r['peak_rss_mb']:>12.0f} "
            f"{r['peak_rss_mb'] / base['peak_rss_mb']:>6.2f} {r['peak_rss_mb'] / AIM_MB:>6.2f} "
            f"{ms:>9.1f} {ms / ms0:>6.2f} {r['mean_kg_h']:>8.4f}"
        )
    worst = max(r["peak_rss_mb"] for r in rows)
    print(
        f"aim (issue 30): peak RSS <= {AIM_MB:.0f} MB; the largest here is {worst:.0f} MB, "
        f"{worst / AIM_MB:.2f} x the aim ({'met' if worst <= AIM_MB else 'not met'})"
    )


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--one":
        print(json.dumps(one(sys.argv[2], float(sys.argv[3]))))
    else:
        main([float(a) for a in sys.argv[1:]] or [1.0, 5.0, 20.0])
