"""``qogi synth``: simulate a release and render it into a recording."""

from __future__ import annotations

import argparse
import sys

from .._progress import ProgressBar
from ..errors import UsageError
from ..files import check_outputs
from ..io.hdf5 import open_recording
from ..physics.presets import camera_preset_names
from ..synth import plume as synth
from ..synth.render import synthesize
from ._cli_args import nonnegative_int, positive_float, seed


def cmd_synth(args: argparse.Namespace) -> int:

    if args.list or not args.preset:
        if not args.preset and not args.list:
            print("qogi synth: give a preset name (or --list)", file=sys.stderr)
        for name in synth.presets():
            p = synth.preset(name)
            print(
                f"{name:36s} {p['duration_s']:6.1f} s at {p['camera']['frame_rate_hz']:g} Hz  "
                f"{p['description']}"
            )
        return 0 if args.list else 2
    if not args.output:
        raise UsageError("give the output file with -o REC.h5")
    if args.preset not in synth.presets():
        raise UsageError(f"unknown preset {args.preset!r}; known: {', '.join(synth.presets())}")
    if args.camera is not None:
        known = camera_preset_names()
        if args.camera not in known:
            raise UsageError(
                f"--camera {args.camera!r}: unknown camera preset; known: {', '.join(known)}"
            )
    check_outputs({"-o": args.output})
    bar = ProgressBar(f"{args.preset} ", enabled=not args.quiet)
    try:
        # The recording is written beside the target and renamed onto it at
        # the end (RecordingWriter): interrupted, the old file stays as it was.
        path = synthesize(
            args.preset,
            args.output,
            duration_s=args.duration,
            frame_rate_hz=args.frame_rate,
            seed=args.seed,
            noise=not args.no_noise,
            truth_maps=args.truth_maps,
            camera_name=args.camera,
            progress=bar,
            num_threads=args.threads,
        )
    finally:
        bar.close()
    if not args.quiet:
        with open_recording(path) as rec:
            if rec.truth is None:  # render() always writes the truth
                raise RuntimeError(f"{path}: the rendered recording has no truth group")
            rates = ", ".join(
                f"{sp} {v * 3600:.4g} kg/h" for sp, v in rec.truth.emission_rate_kg_s.items()
            )
            print(
                f"wrote {path}: {rec.n_frames} frames x {rec.n_channels} channels x "
                f"{rec.height}x{rec.width}, {rec.duration_s:.2f} s; true emission {rates}"
            )
    return 0


def add_commands(sub) -> None:
    s = sub.add_parser(
        "synth",
        help="simulate a gas release and render it as a recording with exact truth",
        description="Simulate a turbulent buoyant release (Lagrangian puffs on a similarity "
        "mean flow, docs/synthetic.md) and render it through a camera preset "
        "into a recording (docs/recording.md contract) whose /truth holds the exact "
        "emission rate and per-frame mass flux through horizontal planes. "
        "Presets mirror the thesis's releases: `qogi synth --list`.",
        epilog="example: qogi synth lab-ch4-5slpm-gf320 -o lab.h5 --duration 5 --seed 1",
    )
    s.add_argument("preset", nargs="?", help="preset name (see --list)")
    s.add_argument("-o", "--output", help="recording to write (.h5)")
    s.add_argument("--list", action="store_true", help="list the presets and exit")
    s.add_argument(
        "--duration", type=positive_float, help="seconds to render (default: the preset's)"
    )
    s.add_argument(
        "--frame-rate", type=positive_float, help="frames per second (default: the camera's)"
    )
    s.add_argument("--seed", type=seed, default=0, help="random seed (turbulence and noise)")
    s.add_argument("--no-noise", action="store_true", help="leave out the camera's NETD noise")
    s.add_argument(
        "--truth-maps",
        action="store_true",
        help="also store per-frame truth column-density and velocity maps (large)",
    )
    s.add_argument(
        "--camera",
        help="render through another camera preset (e.g. fast-m150), "
        "same pixel footprint at the plume",
    )
    s.add_argument(
        "--threads", type=nonnegative_int, default=0, help="worker threads (0 = all cores)"
    )
    s.add_argument("-q", "--quiet", action="store_true", help="no progress bar or summary")
    s.set_defaults(func=cmd_synth)
