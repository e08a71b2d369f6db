"""``qogi envelope``: the operating envelope on a grid of synthetic releases."""

from __future__ import annotations

import argparse
import sys

from ..errors import EXIT_INTERRUPTED, EXIT_OK, UsageError


def cmd_envelope(args: argparse.Namespace) -> int:
    try:
        from . import envelope  # optional: Dask, pandas and pyarrow (qogi[batch])
    except ImportError as e:
        raise UsageError(
            f"qogi envelope needs Dask, pandas and pyarrow ({e}); install them with: "
            "pip install 'qogi[batch]'"
        ) from None
    if args.list:
        g = envelope.load_grid(args.grid)
        if g.description:
            print(g.description)
        for c in g.cells:
            print(f"{c.block}: {c.name}")
        for scene, why in envelope.excluded_scenes(g):
            print(f"left out: {scene} (every seed): {why}")
        print(f"{len(g.cells)} renderings, {len(g.excluded)} cells left out")
        return EXIT_OK
    if args.output is None:
        raise UsageError("give the output folder: -o OUTDIR (or --list to see the grid's cells)")
    try:
        envelope.run(
            args.grid,
            args.output,
            workers=args.workers,
            threads=args.threads,
            resume=args.resume,
            plots=args.plots,
            progress=not args.quiet,
        )
    except KeyboardInterrupt:
        print(
            f"qogi envelope: interrupted; what is done is kept in {args.output}: run the "
            "same command with --resume to finish",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    return EXIT_OK


def add_commands(sub) -> None:
    e = sub.add_parser(
        "envelope",
        help="the operating envelope: error, coverage and detection on a grid of synthetic "
        "releases",
        description="Render a grid of synthetic releases with exact truth (rate, distance, "
        "gas-background contrast in emission and absorption, wind, background, camera, "
        "record length, seeds; a TOML file or the built-in 'default' or 'small'), quantify "
        "each with qogi's defaults and the source given on Dask (qogi batch), and write "
        "OUTDIR/cells.csv (per cell, seed and surface: truth, rate, error, interval, "
        "detection, warnings, the scene's signal-to-noise) and OUTDIR/envelope.csv (per "
        "cell: mean error, spread, coverage, detection and warning fractions). Cells the "
        "simulator cannot express are left out with the reason. See "
        "docs/validation/envelope.md.",
        epilog="exit status: 0 done (failed renderings are rows with status 'failed'); 2 bad "
        "grid or arguments; 130 interrupted (what is done is kept: rerun with --resume). "
        "example: qogi envelope small -o env --workers 1 --threads 1 --plots",
    )
    e.add_argument("grid", help="grid: a TOML file, or 'default' or 'small' (built in)")
    e.add_argument("-o", "--output", metavar="OUTDIR", help="output folder")
    e.add_argument("--list", action="store_true", help="print the grid's cells and exit")
    e.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="Dask worker processes for the quantification (default: one per CPU)",
    )
    e.add_argument(
        "--threads",
        type=int,
        metavar="N",
        help="engine threads per rendering and per quantification (default: the CPUs shared "
        "among the workers; rendering 1)",
    )
    e.add_argument(
        "--resume",
        action="store_true",
        help="keep the renderings and results already in OUTDIR",
    )
    e.add_argument(
        "--plots",
        action="store_true",
        help="write heat maps of error and coverage (rate x distance, SNR x wind)",
    )
    e.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    e.set_defaults(func=cmd_envelope)
