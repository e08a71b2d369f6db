"""The ``qogi`` command line."""

from __future__ import annotations

import argparse
import sys

from . import __version__


def cmd_info(args: argparse.Namespace) -> int:
    import os

    from .info import (flir_info, format_flir_info, format_recording_info, info_json,
                       recording_info)
    from .io import FLIR_EXTENSIONS
    from .recording import open_recording

    try:
        if os.path.splitext(args.path)[1].lower() in FLIR_EXTENSIONS:
            info = flir_info(args.path)
            text = format_flir_info
        else:
            with open_recording(args.path, nonfinite="invalid" if args.allow_invalid
                                else "error") as rec:
                info = recording_info(rec)
            text = format_recording_info
    except (ValueError, OSError) as e:
        print(f"qogi info: error: {e}", file=sys.stderr)
        return 2
    print(info_json(info) if args.json else text(info))
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="qogi",
        description="Quantitative optical gas imaging: from radiometric MWIR video of a "
                    "gas plume to an emission rate with an uncertainty.")
    p.add_argument("--version", action="version", version=f"qogi {__version__}")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    i = sub.add_parser(
        "info", help="describe a recording (or a FLIR .seq/.csq/.jpg file)",
        description="Print what a recording holds: camera, channels (name, band, centroid), "
                    "frames (T, C, H, W, quantity, duration, frame rate), scene, truth, and "
                    "per-channel min/mean/max of the first frame in band radiance "
                    "[W/(m2 sr)] and radiometric temperature [K]. The file is validated "
                    "first; a bad file gives an error naming the problem and the fix. For "
                    "a FLIR file: frames, camera, Planck calibration, object parameters "
                    "and first-frame counts and temperatures.")
    i.add_argument("path", help="recording (.h5) or FLIR file (.seq, .csq, .fff, .jpg)")
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    i.add_argument("--allow-invalid", action="store_true",
                   help="treat NaN/inf pixels as invalid instead of an error")
    i.set_defaults(func=cmd_info)
    from ._cli_spectra import add_commands as add_spectra_commands
    add_spectra_commands(sub)
    from ._cli_synth import add_commands as add_synth_commands
    add_synth_commands(sub)
    from ._cli_quantify import add_commands as add_quantify_commands
    from ._cli_quantify import add_demo_command
    add_quantify_commands(sub)
    add_demo_command(sub)
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
