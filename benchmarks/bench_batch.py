"""qogi batch throughput: recordings per hour with 1 and 2 local workers (issue 21).

20 short 15 Hz single-channel recordings (GF320 lab release, 320x240, 4 s =
60 frames each; QOGI_BENCH_SCALE scales the length) quantified by
``qogi.apps.batch.run`` on a LocalCluster of 1 worker (the engine gets every CPU)
and of 2 workers (the CPUs shared between them), in the same run; the
baseline is the 1-worker figure and the scaling ratio is 2-worker throughput
over 1-worker throughput (2.0 would be perfect on 2 free cores). The wall
time includes starting the cluster, as a user sees it. The recordings are
four synthetic releases (seeds 0-3) looped to length from five different
start frames: 20 files, each one task.

The load average is printed before and after, and the CPUs the batch
obtained (the tasks' CPU seconds over the wall time): on a machine shared with
other work the ratio says how much a second worker gains under that load, not
on an idle machine. With 1 worker the engine runs 2 threads, with 2 workers 1
each, so both hold two runnable threads; a second worker gains by running the
serial (Python) parts of two recordings at once. QOGI_BENCH_RUNS=2 repeats the
pair (1, 2, 1, 2) to show the spread.
"""

import os
import pathlib
import tempfile
import time

from bench_pipeline import looped  # the same looped recording

from qogi.apps import batch
from qogi.synth import render

N_RECORDINGS = 20
SOURCES = 4
PRESET = "lab-ch4-5slpm-gf320"


def load():
    return "load average {:.1f} {:.1f} {:.1f}".format(*os.getloadavg())


def main():
    duration = 4.0 * float(os.environ.get("QOGI_BENCH_SCALE", "1"))
    repeats = int(os.environ.get("QOGI_BENCH_RUNS", "1"))
    with tempfile.TemporaryDirectory() as tmp:
        d = pathlib.Path(tmp)
        t = time.perf_counter()
        for s in range(SOURCES):
            render.synthesize(PRESET, d / f"src{s}.h5", duration_s=3.0, seed=s)
        lines = ["path,name,surfaces,source,species"]
        for k in range(N_RECORDINGS):
            looped(
                d / f"src{k % SOURCES}.h5",
                d / f"clip{k:02d}.h5",
                duration,
                start=5 * (k // SOURCES),
            )
            lines.append(
                f'clip{k:02d}.h5,clip{k:02d},"100,207,220,207;90,187,230,187","159.5,227",CH4'
            )
        (d / "survey.csv").write_text("\n".join(lines) + "\n")
        print(
            f"{N_RECORDINGS} recordings of {duration:g} s at 15 Hz (320x240, one channel), "
            f"2 surfaces each; made in {time.perf_counter() - t:.0f} s; "
            f"{os.cpu_count()} CPUs"
        )
        per_hour = {1: [], 2: []}
        for rep in range(repeats):
            for workers in (1, 2):
                before = load()
                t = time.perf_counter()
                df = batch.run(
                    d / "survey.csv", d / f"out{rep}-{workers}", workers=workers, progress=False
                )
                wall = time.perf_counter() - t
                ok = int((df["status"] == "ok").sum())
                per_hour[workers].append(3600.0 * N_RECORDINGS / wall)
                truth = df["S1/CH4 truth_kg_h"].iloc[0]
                err = (df["S1/CH4 mean_kg_h"] / truth - 1.0) * 100
                cpu = df["cpu_time_s"].sum()
                print(
                    f"  {workers} worker(s): {wall:6.1f} s wall, {per_hour[workers][-1]:6.0f} "
                    f"recordings/h ({ok}/{N_RECORDINGS} ok; per recording "
                    f"{df['run_time_s'].mean():.1f} s wall and {cpu / len(df):.1f} CPU s in "
                    f"its task; CPUs obtained {cpu / wall:.2f}; S1 error vs truth "
                    f"{err.mean():+.1f} % mean) [{before} -> {load()}]"
                )
        for rep, (one, two) in enumerate(zip(per_hour[1], per_hour[2])):
            print(
                f"  scaling, pair {rep + 1}: 2 workers / 1 worker = {two / one:.2f}x "
                f"(baseline: 1 worker, {one:.0f} recordings/h)"
            )


if __name__ == "__main__":
    main()
