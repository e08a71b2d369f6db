"""``qogi batch``: quantify the recordings of a manifest on Dask."""

from __future__ import annotations

import argparse
import sys

from ..errors import EXIT_DATA, EXIT_INTERRUPTED, EXIT_OK, UsageError


def cmd_batch(args: argparse.Namespace) -> int:
    try:
        from . import batch  # optional: Dask, pandas and pyarrow (qogi[batch])
    except ImportError as e:
        raise UsageError(
            f"qogi batch needs Dask, pandas and pyarrow ({e}); install them with: "
            "pip install 'qogi[batch]'"
        ) from None
    try:
        df = batch.run(
            args.manifest,
            args.output,
            workers=args.workers,
            threads=args.threads,
            scheduler=args.scheduler,
            resume=args.resume,
            overwrite=args.overwrite,
            retries=args.retries,
            timeout_s=args.timeout,
            plots=True if args.plots else None,
            progress=not args.quiet,
        )
    except KeyboardInterrupt:
        print(
            f"qogi batch: interrupted; the rows done are kept in {args.output}: run the same "
            "command with --resume to finish",
            file=sys.stderr,
        )
        return EXIT_INTERRUPTED
    return EXIT_OK if (df["status"] == "ok").all() else EXIT_DATA


def add_commands(sub) -> None:
    b = sub.add_parser(
        "batch",
        help="quantify every recording of a manifest (CSV/TOML) on Dask",
        description="Quantify many recordings: one row per recording in a manifest (.csv or "
        ".toml: path, surfaces or 'auto', source, species, gas temperature, "
        "velocity, camera/distance overrides, any QuantifyConfig field; defaults "
        "in one place), each one Dask task on a local cluster sized to this "
        "machine or on an existing cluster (--scheduler). Writes OUTDIR/<name>/"
        "result.json per row and OUTDIR/summary.csv and summary.parquet. A failed "
        "recording is recorded in its row and does not stop the others; --resume "
        "skips rows already done with the same settings. See docs/batch.md.",
        epilog="exit status: 0 every row ok; 3 some rows failed (see the summary's status and "
        "error columns); 2 bad manifest or arguments; 130 interrupted (the rows done "
        "are kept: rerun with --resume). example: qogi batch survey.toml -o out "
        "--workers 4",
    )
    b.add_argument("manifest", help="manifest file (.csv or .toml, docs/batch.md)")
    b.add_argument("-o", "--output", required=True, metavar="OUTDIR", help="output folder")
    b.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local worker processes (default: one per CPU, at most one per row)",
    )
    b.add_argument(
        "--threads",
        type=int,
        metavar="N",
        help="engine threads per recording (default: the CPUs shared among the workers)",
    )
    b.add_argument(
        "--scheduler",
        metavar="tcp://HOST:PORT",
        help="use this running Dask scheduler instead of a local cluster",
    )
    b.add_argument(
        "--resume",
        action="store_true",
        help="skip rows whose result exists with the same config hash",
    )
    b.add_argument(
        "--overwrite",
        action="store_true",
        help="redo every row although OUTDIR holds a batch already",
    )
    b.add_argument(
        "--retries",
        type=int,
        default=2,
        metavar="N",
        help="reruns of a task that failed for a reason other than bad input "
        "(worker lost, out of memory; default 2)",
    )
    b.add_argument(
        "--timeout",
        type=float,
        metavar="S",
        help="per-recording time limit [s] for rows without timeout_s",
    )
    b.add_argument(
        "--plots",
        action="store_true",
        help="write rates.png (and maps.png, detectability.png) for every row",
    )
    b.add_argument("-q", "--quiet", action="store_true", help="no progress bar or messages")
    b.set_defaults(func=cmd_batch)
