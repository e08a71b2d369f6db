"""``qogi info``: what a recording or a camera file holds."""

from __future__ import annotations

import argparse
import os

from ..errors import DataError, UsageError
from ..io.hdf5 import open_recording
from ..io.open import file_kind
from ._cli_camera import add_scene_options, cmd_info_camera
from .info import flir_info, format_flir_info, format_recording_info, info_json, recording_info


def cmd_info(args: argparse.Namespace) -> int:
    try:
        if os.path.isfile(args.path) and file_kind(args.path) in ("flir", "telops"):
            return cmd_info_camera(args)
        if file_kind(args.path) == "flir":
            info = flir_info(args.path)
            text = format_flir_info
        else:
            with open_recording(
                args.path, nonfinite="invalid" if args.allow_invalid else "error"
            ) as rec:
                info = recording_info(rec)
            text = format_recording_info
    except MemoryError:
        raise
    except (ValueError, OSError) as e:
        if not os.path.isfile(args.path):
            raise UsageError(str(e)) from None
        if isinstance(e, DataError):
            raise
        raise DataError(str(e)) from None
    print(info_json(info) if args.json else text(info))
    return 0


def add_commands(sub) -> None:
    i = sub.add_parser(
        "info",
        help="describe a recording (or a FLIR .seq/.csq/.jpg file)",
        description="Print what a recording holds: camera, channels (name, band, centroid), "
        "frames (T, C, H, W, quantity, duration, frame rate), scene, truth, and "
        "per-channel min/mean/max of the first frame in band radiance "
        "[W/(m2 sr)] and radiometric temperature [K]. The file is validated "
        "first; a bad file gives an error naming the problem and the fix. For "
        "a FLIR file: frames, camera, Planck calibration, object parameters "
        "and first-frame counts and temperatures.",
    )
    i.add_argument(
        "path",
        help="recording (.h5), FLIR file (.seq, .csq, .fff, .jpg) or Telops "
        ".hcc; for a camera file it also says what a conversion needs",
    )
    i.add_argument("--json", action="store_true", help="print JSON instead of text")
    i.add_argument(
        "--allow-invalid",
        action="store_true",
        help="treat NaN/inf pixels as invalid instead of an error",
    )

    add_scene_options(i)
    i.set_defaults(func=cmd_info)
