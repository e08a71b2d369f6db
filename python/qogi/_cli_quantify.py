"""``qogi quantify`` and ``qogi demo``."""

from __future__ import annotations

import argparse
import os
import sys


def _config_from_args(args):
    from .pipeline import QuantifyConfig
    from .surfaces import Region

    gas = "ambient"
    if args.infer_temperature:
        gas = "infer"
    elif args.gas_temperature is not None:
        gas = args.gas_temperature
    velocity = args.velocity
    if args.wind_speed is not None:
        velocity = "wind"
    if args.exit_velocity is not None:
        velocity = "exit"
    background = args.background
    if background not in ("auto", "beside-surface", "percentile"):
        background = Region.parse(background)
    frames = None
    if args.frames:
        a, b = args.frames.split(":")
        frames = (int(a), int(b))
    source = tuple(float(v) for v in args.source.split(",")) if args.source else None
    return QuantifyConfig(species=args.species or ["CH4"], gas_temperature=gas, velocity=velocity,
                          wind_speed_m_s=args.wind_speed, exit_velocity_m_s=args.exit_velocity,
                          averaging=args.averaging, background=background, source=source,
                          distance_m=args.distance, sigma_m=args.sigma, frames=frames,
                          num_threads=args.threads, line_shape=args.line_shape,
                          exit_temperature_K=args.exit_temperature)


def cmd_quantify(args: argparse.Namespace) -> int:
    from ._progress import ProgressBar
    from .pipeline import Cancelled, quantify
    from .recording import open_recording
    from .surfaces import Surface

    try:
        cfg = _config_from_args(args)
        rec = open_recording(args.recording)
        surfaces = [Surface.parse(s, name=f"S{k + 1}") for k, s in enumerate(args.surface or [])]
        if args.auto_surfaces:
            auto, source = _auto(rec, args, cfg)
            surfaces += auto
            if cfg.source is None:
                # The detected source orients the surfaces and gives the
                # default velocimetry its transport flux level.
                cfg.source = source
                if not args.quiet:
                    print(f"qogi quantify: source detected at x={source[0]:.1f}, "
                          f"y={source[1]:.1f} (give --source X,Y to set it)", file=sys.stderr)
        if not surfaces:
            print("qogi quantify: give at least one --surface x0,y0,x1,y1 (or --auto-surfaces)",
                  file=sys.stderr)
            return 2
    except (ValueError, OSError) as e:
        print(f"qogi quantify: error: {e}", file=sys.stderr)
        return 2
    bar = ProgressBar("quantify ", enabled=not args.quiet)
    try:
        result = quantify(rec, surfaces, cfg, progress=bar, keep_maps=bool(args.plot))
    except Cancelled as e:
        bar.close()
        print("qogi quantify: cancelled", file=sys.stderr)
        result = e.partial
        if result is None:
            return 130
    except ValueError as e:
        bar.close()
        print(f"qogi quantify: error: {e}", file=sys.stderr)
        return 2
    bar.close()
    print(result.summary())
    if args.json:
        result.to_json(args.json)
    if args.csv:
        result.to_csv(args.csv)
    if args.plot:
        result.plot(args.plot, kind="rates")
        root, ext = os.path.splitext(args.plot)
        if result.map_frames:
            result.plot(f"{root}_maps{ext or '.png'}", kind="maps")
    return 0 if result.complete else 130


def _auto(rec, args, cfg):
    from .surfaces import auto_surfaces, plume_image

    dists = [float(v) for v in args.auto_surfaces.split(",")]
    return auto_surfaces(plume_image(rec), dists, source=cfg.source, return_source=True)


def add_commands(sub) -> None:
    q = sub.add_parser(
        "quantify", help="emission rate of a recording through control surfaces",
        description="Quantify the emission rate (kg/h, with a 90%% interval) of each species "
                    "through each control surface: background, per-pixel column density "
                    "(inversion of the radiative transfer), velocimetry, flux (thesis eq. 12). "
                    "Flux is positive along a surface's left-hand normal walking from its first "
                    "point to its last as displayed (x right, y down): a horizontal line drawn "
                    "left to right counts upward flow as positive; --source orients every "
                    "surface away from the source instead.",
        epilog="example: qogi quantify lab.h5 --surface 100,207,220,207 --species CH4 "
               "--source 159.5,227 --json out.json --csv out.csv --plot out.png")
    q.add_argument("recording", help="recording file (.h5, DESIGN.md contract)")
    q.add_argument("--surface", action="append", metavar="X0,Y0,X1,Y1[,X2,Y2...]",
                   help="a control surface (line or polyline) in pixels; repeatable")
    q.add_argument("--auto-surfaces", metavar="D1,D2,...",
                   help="detect the plume and place surfaces at these distances (px) from the source")
    q.add_argument("--species", action="append", help="species to quantify (repeatable; default CH4)")
    t = q.add_mutually_exclusive_group()
    t.add_argument("--gas-temperature", type=float, metavar="K",
                   help="gas temperature at the plume centre [K] (default: ambient)")
    t.add_argument("--infer-temperature", action="store_true",
                   help="infer the gas temperature (needs >= 2 channels)")
    v = q.add_mutually_exclusive_group()
    v.add_argument("--velocity", default="fluid", type=lambda m: m.replace("-", "_"),
                   choices=["fluid", "horn_schunck", "lucas_kanade", "farneback", "dis", "piv"],
                   help="velocimetry method (default: fluid, the continuity-equation flow)")
    v.add_argument("--wind-speed", type=float, metavar="M_S",
                   help="use this speed [m/s] normal to every surface instead of velocimetry")
    v.add_argument("--exit-velocity", type=float, metavar="M_S",
                   help="use the release's exit velocity [m/s] (lab checks)")
    q.add_argument("--source", metavar="X,Y", help="source pixel: orient surfaces away from it")
    q.add_argument("--background", default="auto",
                   help="auto (default: beside the surfaces where the strips there are "
                        "gas-free, else the temporal percentile), beside-surface, percentile, "
                        "or a gas-free region x0,y0,x1,y1")
    q.add_argument("--averaging", default="per-frame", choices=["per-frame", "time-averaged"],
                   help="invert every frame then average rates (default), or invert the "
                        "time-averaged frames")
    q.add_argument("--line-shape", default="fixed:25+self", metavar="RULE",
                   help="line shape of the cross-sections: the wing rule fixed[:CM1] or hapi "
                        "(50 half-widths), then +self or +air broadening (default "
                        "fixed:25+self; docs/forward_model.md)")
    q.add_argument("--exit-temperature", type=float, metavar="K",
                   help="the gas's temperature at the exit [K], when known: checked against "
                        "the assumed gas temperature (warning gas-temperature-suspect)")
    q.add_argument("--distance", type=float, metavar="M", help="override the camera distance [m]")
    q.add_argument("--sigma", type=float, metavar="M",
                   help="plume depth sigma [m] (default: from the plume width across each surface)")
    q.add_argument("--frames", metavar="START:STOP", help="frame range")
    q.add_argument("--threads", type=int, default=0, help="worker threads (0 = all cores)")
    q.add_argument("--json", metavar="OUT.json", help="write the result as JSON")
    q.add_argument("--csv", metavar="OUT.csv", help="write the rate time series as CSV")
    q.add_argument("--plot", metavar="OUT.png",
                   help="write the rate plot (and OUT_maps.png with column and velocity maps)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    q.set_defaults(func=cmd_quantify)


def cmd_demo(args: argparse.Namespace) -> int:
    """Synthesise a release with exact truth, quantify it, compare, plot."""
    import numpy as np

    from . import synth
    from ._progress import ProgressBar
    from .pipeline import QuantifyConfig, quantify
    from .recording import open_recording
    from .render import synthesize
    from .surfaces import Surface

    out = os.path.abspath(args.output)
    os.makedirs(out, exist_ok=True)
    preset = args.preset
    p = synth.preset(preset)
    rec_path = os.path.join(out, f"{preset}.h5")
    print(f"qogi demo: {p['description']}")
    print(f"1. simulating and rendering {args.duration:g} s of {preset} "
          f"(seed {args.seed}) -> {rec_path}")
    synthesize(preset, rec_path, duration_s=args.duration, seed=args.seed,
               progress=ProgressBar("   synth ", enabled=not args.quiet))
    rec = open_recording(rec_path)
    ex, ey = p["scene"]["exit_pixel"]
    pix = rec.scene.distance_m * rec.camera.ifov_rad
    surfaces = []
    for h_cm in (4, 8, 12):
        row = ey - h_cm / 100.0 / pix
        half = max(25.0, 0.6 * h_cm / 100.0 / pix + 20)
        surfaces.append(Surface([(max(0.0, ex - half), row), (min(rec.width - 1.0, ex + half), row)],
                                name=f"{h_cm} cm above exit"))
    species = list(rec.scene.species) or ["CH4"]
    cfg = QuantifyConfig(species=species,
                         gas_temperature="infer" if rec.n_channels >= 2 else "ambient",
                         source=(ex, ey))
    print(f"2. quantifying {len(surfaces)} surfaces, species {', '.join(species)}, gas temperature "
          f"{cfg.gas_temperature}, velocity: {cfg.velocity} flow")
    result = quantify(rec, surfaces, cfg, progress=ProgressBar("   quantify ", enabled=not args.quiet),
                      keep_maps=True)
    print("3. result (estimate vs truth):")
    print(result.summary())
    result.to_json(os.path.join(out, "result.json"))
    result.to_csv(os.path.join(out, "result.csv"))
    result.plot(os.path.join(out, "rates.png"), kind="rates")
    result.plot(os.path.join(out, "maps.png"), kind="maps")
    print(f"4. wrote {out}/result.json, result.csv, rates.png (emission-rate time series per "
          f"surface), maps.png (column density and velocity)")
    return 0


def add_demo_command(sub) -> None:
    d = sub.add_parser(
        "demo", help="synthesise a release with exact truth, quantify it, compare and plot",
        description="The main job end to end on a synthetic release whose true emission rate "
                    "is known exactly: simulate and render a preset (qogi synth), quantify it "
                    "through three control surfaces (qogi quantify), print the estimate against "
                    "the truth with its 90%% interval, and write plots.")
    d.add_argument("--preset", default="lab-ch4-5slpm-gf320", help="synthetic preset (qogi synth --list)")
    d.add_argument("--duration", type=float, default=10.0, help="seconds to simulate (default 10)")
    d.add_argument("--seed", type=int, default=1)
    d.add_argument("-o", "--output", default="qogi-demo", help="output folder (default ./qogi-demo)")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=cmd_demo)
