"""Speed of every velocimetry method on 320 x 256 frames (frames per second).

A moving texture (rotation + drift, ~1-3 px/frame, exactly rendered) is
processed as a warm-started sequence, as a camera stream would be. Each
figure is printed against two baselines timed in the same run:

* ``cv2 Farneback``: OpenCV-Python's Farneback flow with its documented
  example parameters on 8-bit frames (the optical flow most QOGI scripts use);
* ``cv2 DIS ultrafast`` / ``cv2 DIS medium``: OpenCV-Python's dense inverse
  search with its presets on 8-bit frames (the fastest dense flow at hand);
* ``frame copy``: copying the frame pair (the memory-bound floor).

The mean end-point error against the exact motion is printed alongside, so a
fast but wrong setting shows. Timings are the best of three runs (other
processes share the cores). The target for the default method is >= 500
frames/s on both cores (issue 20: a 100 Hz four-channel camera delivers 400
channel-frames per second).

Each method runs on one worker (the engine's threads share each frame pair)
and, with --threads > 1 cores, on one worker per core (the sequence split into
chunks, each on one engine thread; see optical_flow_sequence(workers=...)).

The machine is shared: the load average (1 min) is printed before and after,
and each method's CPU time per frame pair (all threads) next to its wall
time, so that the speed an unloaded machine would deliver can be read off.

Then the default method against Farneback on four kinds of content, each
timed in the same run with its end-point error where the motion is known
(so that speed is not bought with accuracy):

* ``synthetic``: the rotating texture above;
* ``flir``: a real infrared scene (the FLIR sample ``SampleSEQ.seq``, read
  by qogi's FLIR reader, as a column-like field: the temperature excess over
  its 1st percentile) moved by the same rotation and drift, sampled bicubically
  from the frame (its mirror-extended plane) at the exact back-traced points;
* ``rendered``: a plume rendered by qogi's simulator (the 5 SLPM CH4 lab
  preset at 100 Hz, exact column density with the exit as the fluid flow's
  source), against the simulator's mass-weighted velocity (the one a flux
  needs), the error weighted by column density;
* ``real-plume``: a real plume sequence (the Villarrica SO2-camera images,
  512 x 512, no truth: speed only).

The FLIR and plume files are not part of qogi: they are looked for in
``$QOGI_SHARED_DIR/samples`` (default: a ``shared`` folder beside the
checkout), and a case whose files are absent is skipped with the reason.

Usage: python benchmarks/bench_velocimetry.py [--frames N] [--threads N] [--methods a,b]
       [--cases synthetic,flir,rendered,real-plume]
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import cv2
import numpy as np

import qogi
from qogi import io as qio
from qogi import synth
from qogi.measure import velocimetry as vel

H, W = 256, 320
TARGET_FPS = 500.0
#: Rotation [rad] about the centre and drift (dx, dy) [px] per frame.
MOTION = (0.01, 1.2, -0.8)
#: Third-party sample files (not shipped with qogi).
SHARED = Path(os.environ.get("QOGI_SHARED_DIR", Path(__file__).resolve().parents[2] / "shared"))
CASES = ("synthetic", "flir", "rendered", "real-plume")
#: Edge ignored by the end-point errors [px].
MARGIN = 16


def texture(seed=7, n=48):
    rng = np.random.default_rng(seed)
    lam = rng.uniform(6.0, 24.0, n)
    ang = rng.uniform(0, 2 * np.pi, n)
    kx, ky = 2 * np.pi / lam * np.cos(ang), 2 * np.pi / lam * np.sin(ang)
    ph = rng.uniform(0, 2 * np.pi, n)

    def t(x, y):
        out = np.zeros(x.shape)
        for i in range(n):
            out += np.cos(kx[i] * x + ky[i] * y + ph[i])
        return out * np.sqrt(2.0 / n)

    return t


def moved(sample, n_frames):
    """Frames of a pattern moved each frame by the map phi(x) = c + R (x - c) + d
    (MOTION: rotation about the centre c of the H x W frame, drift d).
    ``sample(px, py)`` gives the pattern at points (px, py) [px]; frame k at x
    is the pattern at phi^-k(x). Returns the frames and the exact forward
    displacement phi(x) - x [px/frame]."""
    y, x = np.mgrid[0:H, 0:W].astype(float)
    th, dx, dy = MOTION
    cx, cy = W / 2, H / 2
    c, s = np.cos(th), np.sin(th)
    frames = []
    px, py = x.copy(), y.copy()  # phi^-k(x), built up one inverse step at a time
    for _ in range(n_frames):
        frames.append(sample(px, py))
        ux, uy = px - cx - dx, py - cy - dy  # phi^-1(p) = c + R^-1 (p - c - d)
        px, py = cx + c * ux + s * uy, cy - s * ux + c * uy
    tu = cx + c * (x - cx) - s * (y - cy) + dx - x
    tv = cy + s * (x - cx) + c * (y - cy) + dy - y
    return np.array(frames, np.float32), tu, tv


def sequence(n_frames):
    """The synthetic texture (exp(0.4 T), rendered exactly at each point)
    moved by MOTION, with 1 % noise; frames and exact displacement."""
    t = texture()
    frames, tu, tv = moved(lambda px, py: np.exp(0.4 * t(px, py)), n_frames)
    rng = np.random.default_rng(1)
    frames += rng.normal(0, 0.01 * frames.std(), frames.shape).astype(np.float32)
    return frames, tu, tv


def flir_sequence(n_frames):
    """The FLIR sample's first frame (SampleSEQ.seq, 640 x 480, read by
    qogi's reader) as a column-like field, the temperature excess over its
    1st percentile, its centre moved by MOTION: the frame's mirror-extended
    plane sampled bicubically at the back-traced points (the motion is exact
    there, the mirror seams included). None and the reason when the sample
    is absent."""
    path = SHARED / "samples" / "flir" / "SampleSEQ.seq"
    if not path.is_file():
        return None, f"FLIR sample not found at {path} (set QOGI_SHARED_DIR)"
    temp = np.asarray(qio.read_flir(path)[0].temperature(), np.float32)
    field = np.clip(temp - np.percentile(temp, 1), 0, None)
    oy, ox = (field.shape[0] - H) / 2, (field.shape[1] - W) / 2

    def sample(px, py):
        return cv2.remap(
            field,
            (px + ox).astype(np.float32),
            (py + oy).astype(np.float32),
            cv2.INTER_CUBIC,
            borderMode=cv2.BORDER_REFLECT,
        )

    frames, tu, tv = moved(sample, n_frames)
    return (frames, tu, tv), None


PLUME_PRESET, PLUME_RATE_HZ, PLUME_SEED = "lab-ch4-5slpm-gf320", 100.0, 0


def rendered_plume(n_frames):
    """A plume from qogi's simulator (PLUME_PRESET at PLUME_RATE_HZ): exact
    CH4 column density frames (normalised by their 99.5th percentile, as the
    pipeline does), the exit as source mask, and the mass-weighted velocity
    [px/frame] of each pair (mean of its two frames; NaN without gas)."""
    sim = synth.simulate_preset(
        PLUME_PRESET,
        duration_s=n_frames / PLUME_RATE_HZ,
        frame_rate_hz=PLUME_RATE_HZ,
        seed=PLUME_SEED,
    )
    view, rel = sim.view, sim.release
    fp = view.distance_m * view.ifov_rad  # pixel footprint [m]
    col = np.empty((sim.num_frames, view.height_px, view.width_px), np.float32)
    tu, tv = np.empty_like(col), np.empty_like(col)
    for t in range(sim.num_frames):
        m = sim.truth_maps(t)
        col[t] = m["column_kg_m2"]["CH4"]
        tu[t] = m["velocity_x_m_s"] / (fp * PLUME_RATE_HZ)
        tv[t] = -m["velocity_z_m_s"] / (fp * PLUME_RATE_HZ)  # z up, rows down
    exit_row = 0.5 * (view.height_px - 1) - (rel.stack_height_m - view.center_z_m) / fp
    exit_col = 0.5 * (view.width_px - 1) + (rel.exit_x_m - view.center_x_m) / fp
    half = 0.5 * rel.exit_diameter_m / fp + 1.0
    source = np.zeros(col.shape[1:], bool)
    source[
        int(round(exit_row)) :, int(np.floor(exit_col - half)) : int(np.ceil(exit_col + half)) + 1
    ] = True
    col /= np.percentile(col, 99.5)
    return col, 0.5 * (tu[:-1] + tu[1:]), 0.5 * (tv[:-1] + tv[1:]), source


def real_plume(n_frames):
    """The first n_frames of the Villarrica sequence (16-bit PNG, SO2
    absorbance, zero where there is none) as float32, or None and the
    reason when the folder is absent."""
    folder = SHARED / "samples" / "plumes" / "villarrica"
    names = sorted(folder.glob("*.png")) if folder.is_dir() else []
    if len(names) < 2:
        return None, f"real plume sequence not found at {folder} (set QOGI_SHARED_DIR)"
    frames = [cv2.imread(str(p), cv2.IMREAD_UNCHANGED) for p in names[:n_frames]]
    return np.array(frames, np.float32), None


def to_8bit(frames):
    """The frames mapped linearly to 8 bits over the sequence's range (the
    input of OpenCV's Farneback and DIS baselines)."""
    lo, hi = float(frames.min()), float(frames.max())
    scale = 255.0 / (hi - lo) if hi > lo else 1.0
    return [np.clip((f - lo) * scale + 0.5, 0, 255).astype(np.uint8) for f in frames]


def farneback(f8):
    """OpenCV's Farneback flow (its documented example parameters) of every
    consecutive pair: (u, v), each (T - 1, H, W)."""
    out = np.array(
        [
            cv2.calcOpticalFlowFarneback(f8[k], f8[k + 1], None, 0.5, 3, 15, 3, 5, 1.2, 0)
            for k in range(len(f8) - 1)
        ]
    )
    return out[..., 0], out[..., 1]


def best_of(fn, repeats=3):
    """Best wall time and the CPU time (all threads) of that run [s]."""
    best = (np.inf, np.inf)
    for _ in range(repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        fn()
        w, c = time.perf_counter() - w0, time.process_time() - c0
        best = min(best, (w, c))
    return best


def methods_table(frames, tu, tv, methods, cores):
    """Every method in ``methods`` on the synthetic texture, against
    Farneback, DIS and a frame copy timed in the same run."""
    pairs = len(frames) - 1
    f8 = to_8bit(frames)

    def copy():
        for k in range(pairs):
            frames[k].copy()
            frames[k + 1].copy()

    def dis(preset):
        d = cv2.DISOpticalFlow_create(preset)

        def run():
            for k in range(pairs):
                d.calc(f8[k], f8[k + 1], None)

        return run

    w, c = best_of(lambda: farneback(f8))
    base_fb = pairs / w
    print(f"baseline cv2 Farneback : {base_fb:8.1f} frames/s  ({pairs / c:.1f} per core)")
    baselines = {"cv2 Farneback": (base_fb, pairs / c)}
    for name, preset in (
        ("cv2 DIS ultrafast", cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST),
        ("cv2 DIS medium", cv2.DISOPTICAL_FLOW_PRESET_MEDIUM),
    ):
        w, c = best_of(dis(preset))
        baselines[name] = (pairs / w, pairs / c)
        print(f"baseline {name:<14}: {pairs / w:8.1f} frames/s  ({pairs / c:.1f} per core)")
    w, _ = best_of(copy)
    base_copy = pairs / w
    print(f"baseline frame copy    : {base_copy:8.1f} frames/s")
    print()
    print(
        f"{'method':<14}{'workers':>8}{'frames/s':>10}{'per core':>10}{'CPU ms':>8}"
        f"{'x Farneback':>13}{'x copy':>9}{'mean EPE [px]':>15}"
    )
    margin = (slice(None), slice(MARGIN, -MARGIN), slice(MARGIN, -MARGIN))
    results = {}
    cpu_ms = {}
    for method in methods:
        for workers in (1, cores):
            if workers == cores and cores == 1:
                continue

            def run(method=method, workers=workers):
                return qogi.optical_flow_sequence(frames, method=method, workers=workers)

            seq = run()  # warm-up (allocations, OpenCV initialisation)
            w, c = best_of(run)
            fps = pairs / w
            err = np.hypot(seq.u - tu, seq.v - tv)[margin]
            mean_err = float(err[seq.valid[margin]].mean())
            results[(method, workers)] = fps
            cpu_ms[(method, workers)] = 1000 * c / pairs
            tag = "  (default)" if method == vel.DEFAULT_METHOD else ""
            print(
                f"{method:<14}{workers:>8}{fps:10.1f}{pairs / c:10.1f}{1000 * c / pairs:8.2f}"
                f"{fps / base_fb:13.2f}{fps / base_copy:9.4f}{mean_err:15.3f}{tag}"
            )
    if vel.DEFAULT_METHOD not in methods:
        return
    best = max(v for (m, _), v in results.items() if m == vel.DEFAULT_METHOD)
    best_core = max(
        pairs / (cpu_ms[(m, k)] * pairs / 1000) for (m, k) in cpu_ms if m == vel.DEFAULT_METHOD
    )
    print(
        f"\nsame run, {W} x {H}: frames/s (wall, {cores} cores), per core (CPU time), and "
        f"the default's ratio to each"
    )
    print(f"{'method':<22}{'frames/s':>10}{'per core':>10}{'default / it':>14}")
    print(f"{vel.DEFAULT_METHOD + ' (default)':<22}{best:10.1f}{best_core:10.1f}{1.0:14.2f}")
    for name, (fps, per_core) in baselines.items():
        print(f"{name:<22}{fps:10.1f}{per_core:10.1f}{best / fps:14.2f}")
    verdict = "meets" if best >= TARGET_FPS else "MISSES"
    print(
        f"\ndefault method '{vel.DEFAULT_METHOD}': {best:.1f} frames/s on this machine now, "
        f"{verdict} the {TARGET_FPS:.0f} frames/s target ({best / base_fb:.2f} x cv2 "
        f"Farneback timed alongside)"
    )
    ms = min(v for (m, _), v in cpu_ms.items() if m == vel.DEFAULT_METHOD)
    idle = cores * 1000.0 / ms
    print(
        f"its CPU time: {ms:.2f} ms per frame pair, i.e. {idle:.0f} frames/s on {cores} idle "
        f"cores ({'meets' if idle >= TARGET_FPS else 'MISSES'} the target when the machine "
        f"is not shared)"
    )


def default_flow(frames, source=None):
    """Run the default method warm-started over ``frames`` on one worker and
    on one per core: the best wall frames/s, the frames/s per core of that
    run (CPU time of all threads) and the one-worker flows (the same whatever
    the machine's load; more workers start their chunks from warm-up pairs)."""
    pairs = len(frames) - 1
    best, flows = None, None
    for workers in sorted({1, vel.get_num_threads()}):

        def run(workers=workers):
            return qogi.optical_flow_sequence(frames, source_mask=source, workers=workers)

        seq = run()  # warm-up (allocations, OpenCV initialisation)
        if flows is None:
            flows = seq
        w, c = best_of(run)
        if best is None or pairs / w > best[0]:
            best = (pairs / w, pairs / c)
    return (*best, flows)


def epe(u, v, tu, tv, weight=None):
    """Mean end-point error [px] over the interior (MARGIN px from the edge;
    weighted by ``weight`` where given, where the truth is finite)."""
    sl = (slice(None), slice(MARGIN, -MARGIN), slice(MARGIN, -MARGIN))
    err = np.hypot(u - tu, v - tv)[sl]
    wt = np.ones_like(err) if weight is None else weight[sl]
    ok = np.isfinite(err) & (wt > 0)
    return float((err[ok] * wt[ok]).sum() / wt[ok].sum())


def compare_case(name, frames, truth=None, source=None, weight=None):
    """The default method against Farneback on one sequence: frames/s (wall
    and per core) of each, their ratios and, with ``truth`` (tu, tv), each
    one's mean end-point error. Returns the row's figures."""
    pairs = len(frames) - 1
    f8 = to_8bit(frames)
    w, c = best_of(lambda: farneback(f8))
    fb_wall, fb_core = pairs / w, pairs / c
    fps, per_core, seq = default_flow(frames, source)
    e_def = e_fb = float("nan")
    if truth is not None:
        e_def = epe(seq.u, seq.v, *truth, weight)
        e_fb = epe(*farneback(f8), *truth, weight)
    row = (name, frames.shape, fps, per_core, fb_wall, fb_core, e_def, e_fb)
    print_case(row)
    return row


def print_case(row):
    name, shape, fps, per_core, fb_wall, fb_core, e_def, e_fb = row
    size = f"{shape[0] - 1} x {shape[2]}x{shape[1]}"
    print(
        f"{name:<12}{size:>14}{fps:9.1f}{per_core:9.1f}{fb_wall:9.1f}{fb_core:9.1f}"
        f"{fps / fb_wall:8.2f}{per_core / fb_core:8.2f}{e_def:9.3f}{e_fb:9.3f}",
        flush=True,
    )


def cases_table(cases, n_frames):
    """The default method against Farneback on each of ``cases`` (CASES)."""
    print(
        f"\nthe default method '{vel.DEFAULT_METHOD}' against cv2 Farneback on each kind of "
        f"content, same run; frames/s wall (best of 1 and {vel.get_num_threads()} workers "
        "for the default; Farneback on OpenCV's threads) and per core (CPU time of all "
        "threads); EPE = mean end-point error [px] against the known motion (rendered "
        "plume: the simulator's mass-weighted velocity, weighted by column density)"
    )
    print(
        f"{'case':<12}{'pairs x size':>14}{'default':>9}{'/core':>9}{'Farneb.':>9}{'/core':>9}"
        f"{'x wall':>8}{'x core':>8}{'EPE def':>9}{'EPE Fb':>9}"
    )
    rows = []
    for case in cases:
        if case == "synthetic":
            frames, tu, tv = sequence(n_frames)
            rows.append(compare_case(case, frames, (tu, tv)))
        elif case == "flir":
            seq, why = flir_sequence(n_frames)
            if seq is None:
                print(f"{case:<12}skipped: {why}")
                continue
            frames, tu, tv = seq
            rows.append(compare_case(case, frames, (tu, tv)))
        elif case == "rendered":
            col, tu, tv, source = rendered_plume(min(n_frames, 41))
            # Where the plume is: column above 5 % of the normalised peak.
            weight = np.where(col[:-1] > 0.05, col[:-1], 0.0)
            rows.append(compare_case(case, col, (tu, tv), source, weight))
        elif case == "real-plume":
            frames, why = real_plume(n_frames)
            if frames is None:
                print(f"{case:<12}skipped: {why}")
                continue
            rows.append(compare_case(case, frames))
    if rows:
        worst = min(rows, key=lambda r: r[2] / r[4])
        print(
            f"\nlowest ratio to Farneback: {worst[2] / worst[4]:.2f} x at wall clock "
            f"({worst[0]}), {min(r[3] / r[5] for r in rows):.2f} x per core"
        )
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--frames",
        type=int,
        default=81,
        help="frames per run (default 81: the cold first pair, several "
        "times the cost of a warm one, is amortised as in a stream; the "
        "rendered plume takes at most 41)",
    )
    ap.add_argument("--threads", type=int, default=0, help="engine threads (default 0 = all cores)")
    ap.add_argument(
        "--methods",
        default=",".join(vel.METHODS),
        help="comma-separated engine methods timed on the synthetic texture (default all; "
        "'' for none)",
    )
    ap.add_argument(
        "--cases",
        default=",".join(CASES),
        help=f"comma-separated cases of the default against Farneback (default all: "
        f"{', '.join(CASES)}; '' for none)",
    )
    args = ap.parse_args(argv)
    if args.frames < 3:
        ap.error(f"--frames must be >= 3; got {args.frames}")
    methods = [m for m in args.methods.split(",") if m]
    for m in methods:
        if m not in vel.METHODS:
            ap.error(f"--methods: unknown method {m!r}; choose from {', '.join(vel.METHODS)}")
    cases = [c for c in args.cases.split(",") if c]
    for c in cases:
        if c not in CASES:
            ap.error(f"--cases: unknown case {c!r}; choose from {', '.join(CASES)}")
    vel.set_num_threads(args.threads)
    cores = vel.get_num_threads()
    print(
        f"velocimetry: warm-started sequences ({args.frames} frames), best of 3 runs, "
        f"{cores} engine threads"
    )
    print(
        "frames/s = pairs / wall time; per core = pairs / CPU time of all threads (what "
        "one unloaded core delivers); CPU ms = CPU time of all threads per pair"
    )
    print(f"load average (1 min) before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    if methods:
        print(f"\nevery method on the synthetic texture, {W} x {H}")
        frames, tu, tv = sequence(args.frames)
        methods_table(frames, tu, tv, methods, cores)
    if cases:
        cases_table(cases, args.frames)
    print(f"\nload average (1 min) after: {os.getloadavg()[0]:.2f}")


if __name__ == "__main__":
    main()
