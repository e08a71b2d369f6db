"""``qogi quantify`` and ``qogi demo``."""

from __future__ import annotations

import argparse
import os
import sys


def _config_from_args(args):
    """The QuantifyConfig of the command line: the settings file's
    (``--config``), with every flag given explicitly overriding it."""
    from .config_io import config_from_dict
    from .surfaces import Region

    over = {}
    if args.infer_temperature:
        over["gas_temperature"] = "infer"
    elif args.gas_temperature is not None:
        over["gas_temperature"] = args.gas_temperature
    if args.velocity is not None:
        over["velocity"] = args.velocity
    if args.wind_speed is not None:
        over.update(velocity="wind", wind_speed_m_s=args.wind_speed)
    if args.exit_velocity is not None:
        over.update(velocity="exit", exit_velocity_m_s=args.exit_velocity)
    if args.background is not None:
        over["background"] = (args.background if args.background in ("beside-surface", "percentile")
                              else Region.parse(args.background))
    if args.frames:
        a, b = args.frames.split(":")
        over["frames"] = (int(a), int(b))
    if args.source:
        over["source"] = tuple(float(v) for v in args.source.split(","))
    for key, value in (("species", args.species), ("averaging", args.averaging),
                       ("distance_m", args.distance), ("sigma_m", args.sigma),
                       ("num_threads", args.threads)):
        if value is not None:
            over[key] = value
    base = {}
    if getattr(args, "settings", None) is not None:
        base = args.settings.config.to_dict()
    return config_from_dict({**base, **over})


def cmd_quantify(args: argparse.Namespace) -> int:
    from ._progress import ProgressBar
    from .pipeline import Cancelled, quantify
    from .surfaces import Surface

    try:
        from .config_io import load_settings
        from .units import parse_unit
        args.settings = load_settings(args.config) if args.config else None
        units = parse_unit(args.units) if args.units else \
            ((args.settings.units if args.settings else None) or "kg/h")
        cfg = _config_from_args(args)
        from ._cli_camera import open_input, origin_lines
        rec = open_input(args)
        if not args.quiet and getattr(rec, "scene_origin", None):
            print("qogi quantify: scene: " + "; ".join(origin_lines(rec)), file=sys.stderr)
        surfaces = [Surface.parse(s, name=f"S{k + 1}") for k, s in enumerate(args.surface or [])]
        if not surfaces and not args.auto_surfaces and args.settings is not None:
            surfaces = list(args.settings.surfaces)
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
        result = quantify(rec, surfaces, cfg, progress=bar, keep_maps=bool(args.plot or args.report))
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
    result.units = units
    # With --json - the JSON is the standard output; the summary goes to stderr.
    print(result.summary(), file=sys.stderr if args.json == "-" else sys.stdout)
    if args.json == "-":
        sys.stdout.write(result.to_json() + "\n")
    elif args.json:
        result.to_json(args.json)
    if args.csv:
        result.to_csv(args.csv)
    if args.save_config:
        cfg.to_toml(args.save_config, surfaces, units)
    if args.report:
        from .report import write_report
        write_report(result, args.report, recording=rec)
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
    q.add_argument("recording", help="recording (.h5) or camera file (FLIR .seq/.csq/.jpg/.fff, "
                                     "Telops .hcc: give --camera and the scene facts it lacks; docs/recording.md)")
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
    v.add_argument("--velocity", default=None, type=lambda m: m.replace("-", "_"),
                   choices=["fluid", "horn_schunck", "lucas_kanade", "farneback", "dis", "piv"],
                   help="velocimetry method (default: fluid, the continuity-equation flow)")
    v.add_argument("--wind-speed", type=float, metavar="M_S",
                   help="use this speed [m/s] normal to every surface instead of velocimetry")
    v.add_argument("--exit-velocity", type=float, metavar="M_S",
                   help="use the release's exit velocity [m/s] (lab checks)")
    q.add_argument("--source", metavar="X,Y", help="source pixel: orient surfaces away from it")
    q.add_argument("--background", default=None,
                   help="beside-surface (default), percentile, or a gas-free region x0,y0,x1,y1")
    q.add_argument("--averaging", default=None, choices=["per-frame", "time-averaged"],
                   help="invert every frame then average rates (default), or invert the "
                        "time-averaged frames")
    q.add_argument("--sigma", type=float, metavar="M",
                   help="plume depth sigma [m] (default: from the plume width across each surface)")
    q.add_argument("--frames", metavar="START:STOP", help="frame range")
    q.add_argument("--threads", type=int, default=None, help="worker threads (0 = all cores, the default)")
    q.add_argument("--config", metavar="SETTINGS.toml|RESULT.json",
                   help="take the settings (and surfaces, units) from a settings file or a "
                        "result JSON; flags given explicitly override them")
    q.add_argument("--save-config", metavar="OUT.toml",
                   help="write the settings of this run (with the surfaces) as TOML")
    q.add_argument("--units", metavar="UNIT",
                   help="reporting unit: kg/h (default), g/h, kg/day, t/year, SLPM, scfh, "
                        "mcf/day (volumes at 20 C, 1 atm)")
    q.add_argument("--json", metavar="OUT.json",
                   help="write the result as JSON ('-': to standard output, the summary to stderr)")
    q.add_argument("--csv", metavar="OUT.csv",
                   help="write the rate time series as CSV, and the summary as OUT.summary.csv")
    q.add_argument("--report", metavar="OUT.pdf",
                   help="write a one-recording PDF report (scene, rates, budget, settings)")
    q.add_argument("--plot", metavar="OUT.png",
                   help="write the rate plot (and OUT_maps.png with column and velocity maps)")
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    from ._cli_camera import add_scene_options
    add_scene_options(q)
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
    if args.quick:
        args.duration = min(args.duration, 3.0)
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
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        print(f"4. wrote {out}/result.json, result.csv (plots need matplotlib: "
              "pip install 'qogi[plot]')")
        return 0
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
    d.add_argument("--quick", action="store_true",
                   help="a short run (3 s of video) to check an installation")
    d.add_argument("--seed", type=int, default=1)
    d.add_argument("-o", "--output", default="qogi-demo", help="output folder (default ./qogi-demo)")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=cmd_demo)
