"""The ``qogi`` command line."""

from __future__ import annotations

import argparse
import sys

import numpy as np

from . import __version__


def _demo_channels():
    from .optics import SpectralResponse

    return [
        SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um bandpass"),
        SpectralResponse([1852.0, 6667.0], [1.0, 1.0], name="InSb open 1.5-5.4 um"),
    ]


def cmd_demo(args: argparse.Namespace) -> int:
    channels = _demo_channels()
    temps = np.array([273.15, 288.7, 296.0, 313.15, 363.15, 473.15])
    print("qogi demo: blackbody band radiance [W/(m2 sr)] through ideal channels")
    header = f"{'T [K]':>8}" + "".join(f"  {ch.name:>22}" for ch in channels)
    print(header)
    table = np.array([ch.band_radiance(temps) for ch in channels])
    for i, t in enumerate(temps):
        print(f"{t:8.2f}" + "".join(f"  {table[k, i]:22.6g}" for k in range(len(channels))))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="qogi",
        description="Quantitative optical gas imaging: from radiometric MWIR video of a "
                    "gas plume to an emission rate with an uncertainty.")
    p.add_argument("--version", action="version", version=f"qogi {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    d = sub.add_parser("demo", help="run the demonstration")
    d.set_defaults(func=cmd_demo)
    from ._cli_spectra import add_commands as add_spectra_commands
    add_spectra_commands(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    raise SystemExit(main())
