"""Velocimetry on the synthetic plume presets: mass-weighted velocity on control surfaces.

The study the thesis asked for in its future work (docs/velocimetry.md, "The
plume study"). For each preset, frame rate and seed, a release is simulated
(qogi.synth.plume) and every velocimetry method runs on the sequence of column-density
maps, as the pipeline would run it (warm-started sequence, gas masks from
``plume_mask``, the stack exit as the fluid method's source, invalid vectors
replaced by their valid neighbours). On horizontal control surfaces h = 2 ... 12
cm above the exit it compares the time-averaged mass-weighted normal velocity

    V(h) = sum_t sum_x c_t(x) v_t(x) / sum_t sum_x c_t(x)

(c the truth column density, v the upward velocity at frame t) with the same
sum over the simulation's exact mass-weighted velocity maps, and the flux
sum_x c v dx with the exact plane flux.

Inputs:

* ``truth``: the exact column-density maps (isolates the velocimetry error);
* ``noisy``: the column a per-pixel inversion of the rendered frames would
  return, to first order: the truth column plus the camera's NETD noise
  propagated through each pixel's exact sensitivity dL/dc of every channel
  (rendered through the preset's camera with the renderer's radiative
  transfer, released-gas column scaled by 1.05 at fixed temperature),
  combined over channels by weighted least squares. This is the noise of an
  ideal inversion that knows each pixel's temperature profile and the mixture
  ratio; a real inversion adds its model error on top.

Methods: every method with its defaults, and ``fluid+transport``: the fluid
method's velocity at the frame times with the flux level from the transport
of the line-integrated column (``qogi.measure.velocimetry.calibrate_flux_level``, the
chain of ``plume_frame_velocity``).

Velocity per frame: ``pair`` divides each pair's forward displacement by the
frame interval (what every method returns); ``centred`` averages the forward
displacement of pair (t, t+1) and the inverted one of pair (t-1, t)
(``qogi.measure.velocimetry.frame_velocity``), the velocity at frame t to second order
in the frame interval. ``exact`` rows use the exact displacement maps
(trajectories integrated through the truth velocity maps at 16 sub-steps per
frame): what a perfect pair tracker would return.

Everything is seeded; results are cached under --cache (delete it to redo).

Usage (the table of docs/velocimetry.md: seeds 0 and 1, truth input; every
preset, rate and seed runs every method on a full plume simulation, which is
why results are cached and the first run, which simulates each case, is the
slow one)::

    .venv/bin/python scripts/velocimetry_plume_study.py

Quick look: ``--seeds 0 --methods fluid+transport,fluid --inputs truth``.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import qogi
from qogi import synth
from qogi.measure import velocimetry as vel

PRESETS = ("lab-ch4-5slpm-gf320", "lab-ch4co2-90c-m150")
RATES_HZ = (100.0, 15.0)
HEIGHTS_M = (0.02, 0.04, 0.06, 0.08, 0.10, 0.12)
#: Simulated duration per frame rate [s]: 200 frames at 100 Hz, 150 at 15 Hz.
DURATION_S = {100.0: 2.0, 15.0: 10.0}
#: Pairs dropped at the start of each sequence (warm start settling).
SKIP_PAIRS = 3
ORACLE_SUBSTEPS = 16
REPO = Path(__file__).resolve().parents[1]


# -- cases: simulation and truth ----------------------------------------------


def _geometry(sim, name, heights_m=HEIGHTS_M):
    view = sim.view
    fp = view.distance_m * view.ifov_rad
    cy = 0.5 * (view.height_px - 1)
    exit_z = sim.release.stack_height_m
    exit_row = cy - (exit_z - view.center_z_m) / fp
    cx = 0.5 * (view.width_px - 1)
    exit_col = cx + (sim.release.exit_x_m - view.center_x_m) / fp
    rows = np.array([int(round(exit_row - h / fp)) for h in heights_m])
    heights = (exit_row - rows) * fp
    return fp, exit_row, exit_col, rows, heights


def source_mask(shape, exit_row, exit_col, exit_diameter_m, fp):
    """The stack exit as the fluid method's source: the exit's width plus one
    pixel each side, from the exit row down to the image bottom (gas below the
    exit is inside the pipe)."""
    m = np.zeros(shape, bool)
    half = 0.5 * exit_diameter_m / fp + 1.0
    c0 = int(np.floor(exit_col - half))
    c1 = int(np.ceil(exit_col + half))
    m[int(round(exit_row)) :, max(c0, 0) : c1 + 1] = True
    return m


def _fill(a, gas, sigma=6.0):
    """Velocity where no gas reaches the ray (NaN) by normalised convolution
    of the neighbours (only trajectories leaving the gas pass there)."""
    import cv2

    g = gas.astype(np.float32)
    num = cv2.GaussianBlur(np.where(gas, a, 0).astype(np.float32), (0, 0), sigma)
    den = cv2.GaussianBlur(g, (0, 0), sigma)
    out = np.where(gas, a, num / np.maximum(den, 1e-6))
    return np.where(np.isfinite(out), out, 0).astype(np.float32)


def oracle_displacement(name, rate, seed, duration, fp, num_frames):
    """Exact forward displacement [px/frame] of pairs (t, t+1): trajectories
    integrated through the truth velocity maps (midpoint rule, 16 sub-steps
    per frame, maps of a simulation at 16x the frame rate with the same seed:
    identical frames)."""
    import cv2

    n = ORACLE_SUBSTEPS
    fine = synth.simulate_preset(name, duration_s=duration, frame_rate_hz=rate * n, seed=seed)
    H, W = fine.view.height_px, fine.view.width_px
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    # Velocities in px per fine step, x right and y down.
    k_px = 1.0 / (fp * rate * n)
    cache = {}

    def vel_at(j):
        if j not in cache:
            vx, vz = fine.velocity_maps(j)
            gas = np.isfinite(vx)
            cache[j] = (_fill(vx * k_px, gas), _fill(-vz * k_px, gas))
            for old in [q for q in cache if q < j - 2]:
                del cache[old]
        return cache[j]

    def sample(f, x, y):
        return cv2.remap(f, x, y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)

    out = np.empty((num_frames - 1, 2, H, W), np.float32)
    for t in range(num_frames - 1):
        x, y = xx.copy(), yy.copy()
        for s in range(n):
            j = t * n + s
            u0, v0 = vel_at(j)
            u1, v1 = vel_at(j + 1)
            # Midpoint: velocity at half step, average of the two maps.
            xm = x + 0.5 * sample(u0, x, y)
            ym = y + 0.5 * sample(v0, x, y)
            um = 0.5 * (sample(u0, xm, ym) + sample(u1, xm, ym))
            vm = 0.5 * (sample(v0, xm, ym) + sample(v1, xm, ym))
            x += um
            y += vm
        out[t, 0] = x - xx
        out[t, 1] = y - yy
    return out


def load_case(name, rate, seed, cache_dir, oracle=True, heights_m=HEIGHTS_M):
    """Truth of one simulated release (cached): column (T, H, W) [kg/m2] of
    the released gas, upward mass-weighted velocity vz (T, H, W) [m/s] (0
    where no gas), exact plane flux (T, P) [kg/s], geometry, and the exact
    pair displacements."""
    tag = (
        "" if tuple(heights_m) == HEIGHTS_M else "_h" + "-".join(f"{h * 100:g}" for h in heights_m)
    )
    path = Path(cache_dir) / f"case_{name}_{rate:g}hz_seed{seed}{tag}.npz"
    if path.exists():
        d = dict(np.load(path))
        if oracle and "oracle" not in d:
            pass
        else:
            return d
    duration = DURATION_S[rate]
    sim = synth.simulate_preset(name, duration_s=duration, frame_rate_hz=rate, seed=seed)
    fp, exit_row, exit_col, rows, heights = _geometry(sim, name, heights_m)
    T = sim.num_frames
    H, W = sim.view.height_px, sim.view.width_px
    column = np.empty((T, H, W), np.float32)
    vz = np.empty((T, H, W), np.float32)
    for t in range(T):
        m = sim.truth_maps(t)
        column[t] = sum(m["column_kg_m2"].values())
        vz[t] = np.nan_to_num(m["velocity_z_m_s"])
    planes = synth.horizontal_planes(sim.release.stack_height_m + heights)
    flux = sim.plane_flux(planes)["total"]
    d = dict(
        column=column,
        vz=vz,
        plane_flux=flux,
        fp=fp,
        exit_row=exit_row,
        exit_col=exit_col,
        rows=rows,
        heights=heights,
        rate=rate,
        exit_diameter=sim.release.exit_diameter_m,
        emission=sim.mass_rate_kg_s,
    )
    if oracle:
        d["oracle"] = oracle_displacement(name, rate, seed, duration, fp, T)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez(path, **d)
    return d


# -- the column a per-pixel inversion would deliver ---------------------------


class _ScaledSimulation:
    """A Simulation whose released gas is scaled by ``scale`` (ray samples only),
    at unchanged temperatures: what the renderer needs for dL/dc."""

    def __init__(self, sim, scale):
        self._sim = sim
        self._scale = scale

    def __getattr__(self, name):
        return getattr(self._sim, name)

    def ray_samples(self, *args, **kwargs):
        s = self._sim.ray_samples(*args, **kwargs)
        s["mole_fraction"] = {k: v * np.float32(self._scale) for k, v in s["mole_fraction"].items()}
        return s


def noisy_column(name, rate, seed, case, cache_dir):
    """Truth column + NETD noise through each pixel's sensitivity (cached)."""
    path = Path(cache_dir) / f"noisy_{name}_{rate:g}hz_seed{seed}.npy"
    if path.exists():
        return np.load(path)
    from qogi.physics import camera as camera_mod
    from qogi.synth import render

    p = synth.preset(name)
    _, cam = render._camera_for(p)
    bgd = p["scene"]["background"]
    background = render.Background("plate", bgd["temperature_K"])
    sim = synth.simulate_preset(name, duration_s=DURATION_S[rate], frame_rate_hz=rate, seed=seed)
    r = render.SceneRenderer(sim, cam, background)
    eps = 0.05
    t_bg = background.representative_K()
    sigma_l = camera_mod.netd_radiance_sigma(r.forward.channels, cam.netd_K, t_bg)
    # Gas-free pixels: a thin layer of released gas at the ambient temperature.
    x = 1e-4 * np.array([sim.mole_fractions[s] for s in r.species])
    t_amb = sim.release.ambient_temperature_K
    l_thin = r.forward.band_radiance(x, t_amb, 0.01, t_amb, t_bg) - r.forward.background_radiance(
        t_bg
    )
    c_thin = sum(r.forward.column_density(x, t_amb, 0.01, t_amb).values())
    s0 = np.asarray(l_thin, float).ravel() / c_thin
    r_hi = render.SceneRenderer.__new__(render.SceneRenderer)
    r_hi.__dict__.update(r.__dict__)
    r_hi.sim = _ScaledSimulation(sim, 1.0 + eps)
    column = case["column"]
    T = column.shape[0]
    rng = np.random.default_rng([seed, 7001, int(rate)])
    out = np.empty_like(column)
    for t in range(T):
        l0 = r.render_frame(t).astype(np.float64)
        l1 = r_hi.render_frame(t).astype(np.float64)
        c = column[t].astype(np.float64)
        gas = c > 1e-3 * max(float(c.max()), 1e-30)
        sens = np.where(gas[None], (l1 - l0) / np.maximum(eps * c[None], 1e-30), s0[:, None, None])
        w = sens / sigma_l[:, None, None] ** 2
        noise = rng.normal(0.0, 1.0, l0.shape) * sigma_l[:, None, None]
        out[t] = (c + (w * noise).sum(0) / (w * sens).sum(0)).astype(np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.save(path, out)
    return out


# -- methods -----------------------------------------------------------------


def run_method(frames, method, case, options=None):
    """Displacements [px/frame] of every pair, invalid vectors replaced by the
    median of their valid neighbours."""
    T, H, W = frames.shape
    masks = np.stack([vel.plume_mask(f) for f in frames])
    kw = {}
    if method == "fluid":
        kw["source_mask"] = source_mask(
            (H, W),
            float(case["exit_row"]),
            float(case["exit_col"]),
            float(case["exit_diameter"]),
            float(case["fp"]),
        )
    w0, c0 = time.perf_counter(), time.process_time()
    seq = qogi.optical_flow_sequence(frames, method=method, options=options, masks=masks, **kw)
    wall, cpu = time.perf_counter() - w0, time.process_time() - c0
    u = np.empty_like(seq.u)
    v = np.empty_like(seq.v)
    for k in range(len(seq)):
        if seq.valid[k].all():
            u[k], v[k] = seq.u[k], seq.v[k]
        elif seq.valid[k].any():
            u[k], v[k], _ = vel.replace_vectors(seq.u[k], seq.v[k], seq.valid[k])
        else:
            u[k], v[k] = seq.u[k], seq.v[k]
    return u, v, wall, cpu


def run_spec(frames, spec, case):
    """One study entry: ``METHOD[:FIELD=VALUE...]`` (pair displacements,
    (T - 1, H, W)) or ``fluid+transport`` (frame velocities, (T, H, W)): the
    fluid method with the flux level from the transport of the
    line-integrated column (qogi.measure.velocimetry.calibrate_flux_level)."""
    if spec.endswith("+transport"):
        method, opts = parse_method(spec[: -len("+transport")])
        u, v, wall, cpu = run_method(frames, method, case, opts)
        w0, c0 = time.perf_counter(), time.process_time()
        seq = vel.FlowSequence(
            u, v, np.ones_like(u), np.ones(u.shape, bool), np.zeros(u.shape[0]), method
        )
        fu, fv, _ = vel.calibrate_flux_level(seq, frames, "up", float(case["exit_row"]))
        return fu, fv, wall + time.perf_counter() - w0, cpu + time.process_time() - c0
    method, opts = parse_method(spec)
    return run_method(frames, method, case, opts)


def parse_method(spec):
    """ "fluid:smoothness_scale=0" -> ("fluid", FluidFlowOptions(smoothness_scale=0))."""
    name, *fields = spec.split(":")
    if not fields:
        return name, None
    kw = {}
    for f in fields:
        key, value = f.split("=")
        kw[key] = json.loads(value)
    return name, vel.options_for(name, **kw)


# -- the quantity compared ---------------------------------------------------


def surface_velocity(column, up, rows, frames):
    """Time-averaged mass-weighted upward velocity on each row: sum over the
    frames and the row of column x up / sum of column."""
    c = column[frames][:, rows, :].astype(np.float64)
    return (c * up[frames][:, rows, :]).sum(axis=(0, 2)) / c.sum(axis=(0, 2))


def surface_flux(column, up, rows, frames, fp):
    """Time-averaged flux through each row, sum_x column x up x pixel [kg/s]."""
    c = column[frames][:, rows, :].astype(np.float64)
    return (c * up[frames][:, rows, :]).sum(axis=2).mean(axis=0) * fp


def evaluate(case, u, v, column_in, centred):
    """Errors [%] per height of the mass-weighted velocity (truth-column
    weights) and of the flux (the input column x velocity)."""
    rate, fp, rows = float(case["rate"]), float(case["fp"]), case["rows"]
    col, vz = case["column"], case["vz"]
    T = col.shape[0]
    if u.shape[0] == T:  # already the velocity at the frame times
        if not centred:
            return None
        vt = v
        frames = np.arange(SKIP_PAIRS + 1, T - 1)
    elif centred:
        vt = vel.frame_velocity(u, v)[1]
        frames = np.arange(SKIP_PAIRS + 1, T - 1)
    else:
        vt = np.concatenate([v, v[-1:]])
        frames = np.arange(SKIP_PAIRS, T - 1)
    up = -vt * (fp * rate)
    v_true = surface_velocity(col, vz, rows, frames)
    v_est = surface_velocity(col, up, rows, frames)
    f_true = case["plane_flux"][frames].mean(axis=0)
    f_est = surface_flux(column_in, up, rows, frames, fp)
    return 100 * (v_est / v_true - 1), 100 * (f_est / f_true - 1), v_true


# -- driver --------------------------------------------------------------------


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default=",".join(PRESETS))
    ap.add_argument("--rates", default=",".join(f"{r:g}" for r in RATES_HZ))
    ap.add_argument("--seeds", default="0,1")
    ap.add_argument(
        "--methods",
        default=",".join(["fluid+transport"] + list(vel.METHODS)),
        help="methods; METHOD:FIELD=VALUE:... sets options; fluid+transport is "
        "the fluid method with the flux level from the transport of the "
        "line-integrated column (default: it and every method with its "
        "defaults; fluid:smoothness_scale=0 is the fluid method with the "
        "classic first-order smoothness)",
    )
    ap.add_argument(
        "--inputs",
        default="truth",
        help="truth and/or noisy (the column of an ideal per-pixel inversion "
        "of the rendered frames; slow to make)",
    )
    ap.add_argument(
        "--velocity",
        default="centred",
        help="frame velocity: pair (forward displacement) and/or centred",
    )
    ap.add_argument("--cache", default=str(REPO / "build" / "velstudy"))
    ap.add_argument("--json", default=None, help="write all results to this JSON file")
    ap.add_argument(
        "--figures",
        default=None,
        help="write the figures (error against height) into this directory",
    )
    ap.add_argument("--no-oracle", action="store_true", help="skip the exact-displacement rows")
    ap.add_argument(
        "--heights",
        default=",".join(f"{h:g}" for h in HEIGHTS_M),
        help="control lines above the exit [m] (default 0.02,...,0.12)",
    )
    ap.add_argument(
        "--from-json",
        nargs="+",
        default=None,
        help="print the tables (and figures) of saved results instead of running",
    )
    ap.add_argument(
        "--options",
        default=None,
        help="JSON dict of options for the (single) method given, e.g. "
        "'{\"alpha\": 0.2}' with --methods fluid",
    )
    args = ap.parse_args(argv)
    if args.from_json:
        results = [r for f in args.from_json for r in json.loads(Path(f).read_text())]
        print_tables(results)
        if args.figures:
            plot(results, Path(args.figures))
        return results
    presets = args.presets.split(",")
    rates = [float(r) for r in args.rates.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    methods = args.methods.split(",")
    inputs = args.inputs.split(",")
    modes = args.velocity.split(",")
    heights = tuple(float(h) for h in args.heights.split(","))
    results = []
    for name in presets:
        for rate in rates:
            for seed in seeds:
                t0 = time.perf_counter()
                case = load_case(
                    name, rate, seed, args.cache, oracle=not args.no_oracle, heights_m=heights
                )
                v_true = surface_velocity(
                    case["column"],
                    case["vz"],
                    case["rows"],
                    np.arange(SKIP_PAIRS, case["column"].shape[0] - 1),
                )
                print(
                    f"# {name} {rate:g} Hz seed {seed}: {case['column'].shape[0]} frames, "
                    f"truth V = {', '.join(f'{x:.3f}' for x in v_true)} m/s "
                    f"({time.perf_counter() - t0:.0f} s)",
                    flush=True,
                )
                runs = []
                if not args.no_oracle and "oracle" in case:
                    runs.append(
                        (
                            "exact",
                            "truth",
                            case["oracle"][:, 0],
                            case["oracle"][:, 1],
                            0,
                            0,
                            case["column"],
                        )
                    )
                for inp in inputs:
                    frames = (
                        case["column"]
                        if inp == "truth"
                        else noisy_column(name, rate, seed, case, args.cache)
                    )
                    for spec in methods:
                        if args.options:
                            method, _ = parse_method(spec)
                            u, v, wall, cpu = run_method(
                                frames,
                                method,
                                case,
                                vel.options_for(method, **json.loads(args.options)),
                            )
                        else:
                            u, v, wall, cpu = run_spec(frames, spec, case)
                        runs.append((spec, inp, u, v, wall, cpu, frames))
                for method, inp, u, v, wall, cpu, frames in runs:
                    for mode in modes:
                        got = evaluate(case, u, v, frames, mode == "centred")
                        if got is None:
                            continue
                        ev, ef, vt = got
                        res = dict(
                            preset=name,
                            rate=rate,
                            seed=seed,
                            method=method,
                            input=inp,
                            heights_m=list(map(float, case["heights"])),
                            velocity=mode,
                            v_err=list(map(float, ev)),
                            flux_err=list(map(float, ef)),
                            v_true=list(map(float, vt)),
                            wall_s=wall,
                            cpu_s=cpu,
                            pairs=int(u.shape[0]),
                        )
                        results.append(res)
                        print(
                            f"{method:24s} {inp:6s} {mode:8s} V err % "
                            + " ".join(f"{x:+6.1f}" for x in ev)
                            + "   flux err % "
                            + " ".join(f"{x:+6.1f}" for x in ef)
                            + (f"   {1000 * cpu / u.shape[0]:.1f} ms CPU/pair" if cpu else ""),
                            flush=True,
                        )
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1))
    print()
    print_tables(results)
    if args.figures:
        plot(results, Path(args.figures))
    return results


def _stats(rows, key):
    a = np.array([r[key] for r in rows])
    return a.mean(axis=0), a.min(axis=0), a.max(axis=0)


def print_tables(results):
    """Markdown tables: mean error [%] over seeds (min to max) per height."""
    keys = sorted({(r["input"], r["velocity"]) for r in results})
    for inp, mode in keys:
        sel = [r for r in results if r["input"] == inp and r["velocity"] == mode]
        if not sel:
            continue
        print(f"\n### input: {inp} column, velocity: {mode}\n")
        hs = sel[0].get("heights_m", HEIGHTS_M)
        print(
            "Error of the time-averaged mass-weighted upward velocity [%], mean over seeds "
            "(min / max), heights " + ", ".join(f"{h * 100:.0f}" for h in hs) + " cm\n"
        )
        cases = sorted({(r["preset"], r["rate"]) for r in sel}, key=lambda c: (c[0], -c[1]))
        methods = list(dict.fromkeys(r["method"] for r in sel))
        print("| method | " + " | ".join(f"{p} {rt:g} Hz" for p, rt in cases) + " |")
        print("|---|" + "---|" * len(cases))
        for m in methods:
            cells = []
            for p, rt in cases:
                rs = [r for r in sel if r["method"] == m and r["preset"] == p and r["rate"] == rt]
                if not rs:
                    cells.append("")
                    continue
                mean, lo, hi = _stats(rs, "v_err")
                cells.append(
                    " ".join(f"{x:+.0f}" for x in mean)
                    + (f" ({min(lo):+.0f} / {max(hi):+.0f})" if len(rs) > 1 else "")
                )
            print(f"| {m} | " + " | ".join(cells) + " |")
        if inp != "truth":
            print(
                "\nFlux error [%] (input column x velocity against the exact plane flux), mean:\n"
            )
            print("| method | " + " | ".join(f"{p} {rt:g} Hz" for p, rt in cases) + " |")
            print("|---|" + "---|" * len(cases))
            for m in methods:
                cells = []
                for p, rt in cases:
                    rs = [
                        r for r in sel if r["method"] == m and r["preset"] == p and r["rate"] == rt
                    ]
                    cells.append(
                        " ".join(f"{x:+.0f}" for x in _stats(rs, "flux_err")[0]) if rs else ""
                    )
                print(f"| {m} | " + " | ".join(cells) + " |")


def plot(results, outdir):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    outdir.mkdir(parents=True, exist_ok=True)
    h_cm = np.array(results[0].get("heights_m", HEIGHTS_M)) * 100
    for inp in sorted({r["input"] for r in results}):
        for mode in sorted({r["velocity"] for r in results}):
            sel = [r for r in results if r["input"] == inp and r["velocity"] == mode]
            cases = sorted({(r["preset"], r["rate"]) for r in sel}, key=lambda c: (c[0], -c[1]))
            if not cases:
                continue
            fig, axes = plt.subplots(1, len(cases), figsize=(4.2 * len(cases), 4), sharey=True)
            axes = np.atleast_1d(axes)
            methods = list(dict.fromkeys(r["method"] for r in sel))
            for ax, (p, rt) in zip(axes, cases):
                for m in methods:
                    rs = [
                        r for r in sel if r["method"] == m and r["preset"] == p and r["rate"] == rt
                    ]
                    if not rs:
                        continue
                    mean, lo, hi = _stats(rs, "v_err")
                    (line,) = ax.plot(
                        h_cm, mean, "o-", label=m, lw=2 if m == vel.DEFAULT_METHOD else 1
                    )
                    ax.fill_between(h_cm, lo, hi, color=line.get_color(), alpha=0.15)
                lim = 10 if rt >= 100 else 20
                ax.axhspan(-lim, lim, color="0.9", zorder=0)
                ax.axhline(0, color="k", lw=0.5)
                ax.set_title(f"{p}\n{rt:g} Hz", fontsize=9)
                ax.set_xlabel("height above the exit [cm]")
                ax.set_ylim(-100, 60)
                ax.grid(alpha=0.3)
            axes[0].set_ylabel("error of mass-weighted velocity [%]")
            axes[-1].legend(fontsize=7, loc="lower right")
            fig.suptitle(
                f"input: {inp} column, velocity: {mode} (band: seeds min-max; grey: the target)",
                fontsize=9,
            )
            fig.tight_layout()
            fig.savefig(outdir / f"velocimetry_plume_{inp}_{mode}.png", dpi=80)
            plt.close(fig)


if __name__ == "__main__":
    main()
