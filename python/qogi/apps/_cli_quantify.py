"""``qogi quantify`` and ``qogi demo``."""

from __future__ import annotations

import argparse
import contextlib
import os
import sys
from typing import Any, Dict

from .._interrupts import Terminated, raise_pending
from .._progress import ProgressBar
from ..diagnostics import Diagnostics
from ..errors import EXIT_DATA, EXIT_INTERRUPTED, Cancelled, DataError, UsageError
from ..files import all_or_nothing, check_outputs
from ..io.hdf5 import open_recording
from ..pipeline import QuantifyConfig, _check_inputs, quantify
from ..pipeline.config import load_settings
from ..pipeline.settings import add_arguments, config_overrides
from ..pipeline.surfaces import Surface, auto_surfaces, plume_image
from ..synth import plume as synth
from ..synth.render import synthesize
from ..units import parse_unit
from ._cli_args import positive_float, seed
from ._cli_camera import add_scene_options, open_input, origin_lines
from .report import write_report


def _config_from_args(args):
    """The QuantifyConfig of the command line: the settings file's
    (``--config``), with every flag given explicitly overriding it (each
    checked while parsed: qogi.pipeline.settings)."""

    over: Dict[str, Any] = config_overrides(args)
    if args.distance is not None:  # a scene option (qogi.apps._cli_camera), also the config's
        over["distance_m"] = args.distance
    base = {}
    if getattr(args, "settings", None) is not None:
        base = args.settings.config.to_dict()
    return QuantifyConfig.from_dict({**base, **over})


def _outputs(args: argparse.Namespace) -> dict:
    """The files ``qogi quantify`` writes, by option (the maps plot beside
    --plot, the summary CSV beside --csv)."""
    outs = {
        "--json": None if args.json == "-" else args.json,
        "--csv": args.csv,
        "--plot": args.plot,
        "--report": args.report,
        "--save-config": args.save_config,
    }
    if args.plot:
        root, ext = os.path.splitext(args.plot)
        outs["--plot (maps)"] = f"{root}_maps{ext or '.png'}"
        outs["--plot (detectability)"] = f"{root}_detectability{ext or '.png'}"
    if args.csv:
        root, _ = os.path.splitext(args.csv)
        outs["--csv (summary)"] = f"{root}.summary.csv"
    return outs


@contextlib.contextmanager
def _signals_deferred():
    """Ctrl-C or SIGTERM inside the block takes effect when it ends: the
    outputs are written all together or not at all (each file is atomic; this
    keeps them from being a mix of this run's and an earlier one's)."""
    import signal

    raise_pending()  # a Ctrl-C Python dropped (qogi._interrupts): no output at all
    got: list = []
    old = {}
    for s in (signal.SIGINT, signal.SIGTERM):
        try:
            old[s] = signal.signal(s, lambda signum, frame: got.append(signum))
        except ValueError:  # not the main thread: nothing to defer
            pass
    try:
        yield
    finally:
        for s, h in old.items():
            signal.signal(s, h)
    raise_pending()  # dropped inside the block: the outputs are all written
    if got:
        raise Terminated() if got[0] == signal.SIGTERM else KeyboardInterrupt()


def _untrustworthy(result) -> list:
    """``surface/species`` of every rate whose mean is not a finite number."""
    import math

    return [
        f"{s.surface.name}/{sp}"
        for s in result.surfaces
        for sp, r in s.species.items()
        if not math.isfinite(r.mean_kg_h)
    ]


def cmd_quantify(args: argparse.Namespace) -> int:

    if not os.path.isfile(args.recording):
        raise UsageError(f"{args.recording}: no such file; check the recording's path")
    check_outputs(_outputs(args), inputs=[args.recording])
    try:
        args.settings = load_settings(args.config) if args.config else None
        units = (
            parse_unit(args.units)
            if args.units
            else ((args.settings.units if args.settings else None) or "kg/h")
        )
        cfg = _config_from_args(args)
        rec = open_input(args)
        if not args.quiet and getattr(rec, "scene_origin", None):
            print("qogi quantify: scene: " + "; ".join(origin_lines(rec)), file=sys.stderr)
        surfaces = [Surface.parse(s, name=f"S{k + 1}") for k, s in enumerate(args.surface or [])]
        if not surfaces and not args.auto_surfaces and args.settings is not None:
            surfaces = list(args.settings.surfaces)
        placed = Diagnostics()  # what placing the automatic surfaces did
        if args.auto_surfaces:
            auto, source = _auto(rec, args, cfg, placed)
            if not args.quiet:
                for w in placed:
                    print(f"qogi quantify: warning: {w.message}", file=sys.stderr)
            surfaces += auto
            if cfg.source is None:
                # The detected source orients the surfaces and gives the
                # default velocimetry its transport flux level.
                cfg.source = source
                if not args.quiet:
                    print(
                        f"qogi quantify: source detected at x={source[0]:.1f}, "
                        f"y={source[1]:.1f} (give --source X,Y to set it)",
                        file=sys.stderr,
                    )
        if not surfaces:
            raise UsageError("give at least one --surface x0,y0,x1,y1 (or --auto-surfaces)")
        _check_inputs(rec, surfaces, cfg)  # the call's own mistakes, before any work
    except (UsageError, DataError):
        raise
    except OSError as e:
        raise UsageError(str(e)) from None
    except ValueError as e:  # the recording's own checks (RecordingError) and the surfaces'
        raise UsageError(str(e)) from None
    bar = ProgressBar("quantify ", enabled=not args.quiet)
    try:
        result = quantify(
            rec, surfaces, cfg, progress=bar, keep_maps=bool(args.plot or args.report)
        )
    except (UsageError, DataError):
        raise
    except ValueError as e:
        # The arguments passed their checks: what fails now is the data
        # (e.g. radiance no blackbody can give).
        raise DataError(str(e)) from None
    except (Cancelled, KeyboardInterrupt) as e:
        # Ctrl-C: what was finished is shown, marked partial; the output files
        # are left as they were (a partial result never replaces them).
        bar.close()
        partial = getattr(e, "partial", None)
        if partial is not None:
            print(partial.summary(), file=sys.stderr if args.json == "-" else sys.stdout)
        print("qogi quantify: interrupted; no output file written", file=sys.stderr)
        return EXIT_INTERRUPTED
    finally:
        bar.close()
    result.warnings.extend_unique(placed)
    bad = _untrustworthy(result)
    if bad:
        result.complete = False
    result.units = units
    # With --json - the JSON is the standard output; the summary goes to stderr.
    print(result.summary(), file=sys.stderr if args.json == "-" else sys.stdout)
    with _signals_deferred(), all_or_nothing():
        if args.json == "-":
            sys.stdout.write(result.to_json() + "\n")
        elif args.json:
            result.to_json(args.json)
        if args.csv:
            result.to_csv(args.csv)
        if args.save_config:
            cfg.to_toml(args.save_config, surfaces, units)
        if args.report:
            write_report(result, args.report, recording=rec)
        if args.plot:
            result.plot(args.plot, kind="rates")
            if result.map_frames:
                result.plot(_outputs(args)["--plot (maps)"], kind="maps")
            if result.min_detectable_column_species:
                result.plot(_outputs(args)["--plot (detectability)"], kind="detectability")
    if bad or not result.complete:
        why = f"no finite rate for {', '.join(bad)}" if bad else "the result is incomplete"
        print(
            f"qogi quantify: error: {why}; the result cannot be trusted (see its warnings; "
            'written files say "complete": false)',
            file=sys.stderr,
        )
        return EXIT_DATA
    return 0


def _auto(rec, args, cfg, warnings):
    """Surfaces at the --auto-surfaces distances and the source; a surface
    cut by the image border adds a ``surface-clipped`` warning."""

    try:
        dists = [float(v) for v in args.auto_surfaces.split(",")]
    except ValueError:
        raise ValueError(
            f"--auto-surfaces {args.auto_surfaces!r}: expected distances in "
            "pixels separated by commas, e.g. 40,80"
        ) from None
    image = plume_image(rec)
    try:
        return auto_surfaces(image, dists, source=cfg.source, return_source=True, warnings=warnings)
    except ValueError as e:
        raise UsageError(f"--auto-surfaces {args.auto_surfaces}: {e}") from None


def add_commands(sub) -> None:
    q = sub.add_parser(
        "quantify",
        help="emission rate of a recording through control surfaces",
        description="Quantify the emission rate (kg/h, with a 90% interval) of each species "
        "through each control surface: background, per-pixel column density "
        "(inversion of the radiative transfer), velocimetry, flux (thesis eq. 12). "
        "Flux is positive along a surface's left-hand normal walking from its first "
        "point to its last as displayed (x right, y down): a horizontal line drawn "
        "left to right counts upward flow as positive; --source orients every "
        "surface away from the source instead.",
        epilog="example: qogi quantify lab.h5 --surface 100,207,220,207 --species CH4 "
        "--source 159.5,227 --json out.json --csv out.csv --plot out.png",
    )
    q.add_argument(
        "recording",
        help="recording (.h5) or camera file (FLIR .seq/.csq/.jpg/.fff, "
        "Telops .hcc: give --camera and the scene facts it lacks; docs/recording.md)",
    )
    q.add_argument(
        "--surface",
        action="append",
        metavar="X0,Y0,X1,Y1[,X2,Y2...]",
        help="a control surface (line or polyline) in pixels; repeatable",
    )
    q.add_argument(
        "--auto-surfaces",
        metavar="D1,D2,...",
        help="detect the plume and place surfaces at these distances (px) from the source",
    )
    g = q.add_argument_group(
        "analysis settings",
        "The run's settings (docs/pipeline_api.md, 'Configuration'); a flag given "
        "overrides --config's value.",
    )

    add_arguments(g)
    q.add_argument(
        "--config",
        metavar="SETTINGS.toml|RESULT.json",
        help="take the settings (and surfaces, units) from a settings file or a "
        "result JSON; flags given explicitly override them",
    )
    q.add_argument(
        "--save-config",
        metavar="OUT.toml",
        help="write the settings of this run (with the surfaces) as TOML",
    )
    q.add_argument(
        "--units",
        metavar="UNIT",
        help="reporting unit: kg/h (default), g/h, kg/day, t/year, SLPM, scfh, "
        "mcf/day (volumes at 20 C, 1 atm)",
    )
    q.add_argument(
        "--json",
        metavar="OUT.json",
        help="write the result as JSON ('-': to standard output, the summary to stderr)",
    )
    q.add_argument(
        "--csv",
        metavar="OUT.csv",
        help="write the rate time series as CSV, and the summary as OUT.summary.csv",
    )
    q.add_argument(
        "--report",
        metavar="OUT.pdf",
        help="write a one-recording PDF report (scene, rates, budget, settings)",
    )
    q.add_argument(
        "--plot",
        metavar="OUT.png",
        help=(
            "write the rate plot (and OUT_maps.png with column and velocity maps, "
            "OUT_detectability.png with the minimum-detectable column map)"
        ),
    )
    q.add_argument("-q", "--quiet", action="store_true", help="no progress bar")

    add_scene_options(q)
    q.set_defaults(func=cmd_quantify)


def cmd_demo(args: argparse.Namespace) -> int:
    """Synthesise a release with exact truth, quantify it, compare, plot."""

    out = os.path.abspath(args.output)
    if args.quick:
        args.duration = min(args.duration, 3.0)
    preset = args.preset
    if preset not in synth.presets():
        raise UsageError(f"--preset {preset!r}: unknown; known: {', '.join(synth.presets())}")
    p = synth.preset(preset)
    try:
        os.makedirs(out, exist_ok=True)
    except OSError as e:
        raise UsageError(
            f"-o {args.output}: cannot create the output folder ({e.strerror})"
        ) from None
    rec_path = os.path.join(out, f"{preset}.h5")
    check_outputs(
        {
            "recording": rec_path,
            "result.json": os.path.join(out, "result.json"),
            "result.csv": os.path.join(out, "result.csv"),
            "rates.png": os.path.join(out, "rates.png"),
            "maps.png": os.path.join(out, "maps.png"),
            "detectability.png": os.path.join(out, "detectability.png"),
        }
    )
    print(f"qogi demo: {p['description']}")
    print(
        f"1. simulating and rendering {args.duration:g} s of {preset} "
        f"(seed {args.seed}) -> {rec_path}"
    )
    synthesize(
        preset,
        rec_path,
        duration_s=args.duration,
        seed=args.seed,
        progress=ProgressBar("   synth ", enabled=not args.quiet),
    )
    rec = open_recording(rec_path)
    ex, ey = p["scene"]["exit_pixel"]
    pix = rec.scene.distance_m * rec.camera.ifov_rad
    surfaces = []
    for h_cm in (4, 8, 12):
        row = ey - h_cm / 100.0 / pix
        half = max(25.0, 0.6 * h_cm / 100.0 / pix + 20)
        surfaces.append(
            Surface(
                [(max(0.0, ex - half), row), (min(rec.width - 1.0, ex + half), row)],
                name=f"{h_cm} cm above exit",
            )
        )
    species = list(rec.scene.species) or ["CH4"]
    cfg = QuantifyConfig(
        species=species,
        gas_temperature="infer" if rec.n_channels >= 2 else "ambient",
        source=(ex, ey),
    )
    print(
        f"2. quantifying {len(surfaces)} surfaces, species {', '.join(species)}, gas temperature "
        f"{cfg.gas_temperature}, velocity: {cfg.velocity} flow"
    )
    result = quantify(
        rec,
        surfaces,
        cfg,
        progress=ProgressBar("   quantify ", enabled=not args.quiet),
        keep_maps=True,
    )
    print("3. result (estimate vs truth):")
    print(result.summary())
    import importlib.util

    plots = importlib.util.find_spec("matplotlib") is not None

    with all_or_nothing():  # the demo's outputs together or none (a full disk)
        result.to_json(os.path.join(out, "result.json"))
        result.to_csv(os.path.join(out, "result.csv"))
        if plots:
            result.plot(os.path.join(out, "rates.png"), kind="rates")
            result.plot(os.path.join(out, "maps.png"), kind="maps")
            result.plot(os.path.join(out, "detectability.png"), kind="detectability")
    if not plots:
        print(
            f"4. wrote {out}/result.json, result.csv (plots need matplotlib: "
            "pip install 'qogi[plot]')"
        )
        return 0
    print(
        f"4. wrote {out}/result.json, result.csv, rates.png (emission-rate time series per "
        f"surface), maps.png (column density and velocity), detectability.png "
        f"(minimum-detectable column)"
    )
    return 0


def add_demo_command(sub) -> None:
    d = sub.add_parser(
        "demo",
        help="synthesise a release with exact truth, quantify it, compare and plot",
        description="The main job end to end on a synthetic release whose true emission rate "
        "is known exactly: simulate and render a preset (qogi synth), quantify it "
        "through three control surfaces (qogi quantify), print the estimate against "
        "the truth with its 90% interval, and write plots.",
    )
    d.add_argument(
        "--preset", default="lab-ch4-5slpm-gf320", help="synthetic preset (qogi synth --list)"
    )
    d.add_argument(
        "--duration", type=positive_float, default=10.0, help="seconds to simulate (default 10)"
    )
    d.add_argument(
        "--quick", action="store_true", help="a short run (3 s of video) to check an installation"
    )
    d.add_argument("--seed", type=seed, default=1, help="random seed (default 1)")
    d.add_argument(
        "-o", "--output", default="qogi-demo", help="output folder (default ./qogi-demo)"
    )
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=cmd_demo)
