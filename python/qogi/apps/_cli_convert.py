"""``qogi convert``: any supported file -> a qogi HDF5 recording, streaming,
written atomically."""

from __future__ import annotations

import argparse
import json
import os
import sys
from typing import Optional

from .._progress import ProgressBar
from ..files import atomic_path, check_outputs
from ..io.recording import write_recording
from ._cli_camera import add_scene_options, open_input, origin_lines


def convert(
    rec, out, *, compression: Optional[str] = None, progress=None, batch_bytes: int = 64 << 20
) -> str:
    """Write the recording ``rec`` (e.g. a camera file opened with
    :func:`qogi.open_recording`) to ``out`` as a qogi HDF5 recording.

    Streams in blocks of about ``batch_bytes`` (a camera file is never read
    whole) into a temporary file beside ``out`` that replaces it only when
    complete (:func:`qogi.files.atomic_path`). The scene facts' origins, the
    opening warnings, the source file and (filter wheel) each channel's mean
    time offset are kept as root attributes. Returns ``out``.
    """
    import numpy as np

    _, c, h, w = rec.shape
    extra: dict = {
        f"origin_{k}": str(v) for k, v in (getattr(rec, "scene_origin", None) or {}).items()
    }
    warns = getattr(rec, "warnings", None) or []
    if warns:
        extra["source_warnings"] = json.dumps([d.to_dict() for d in warns])
    ct = getattr(rec, "channel_time_s", None)
    if ct is not None:
        extra["channel_time_offset_s"] = np.asarray(
            ct - np.asarray(ct).mean(axis=1, keepdims=True)
        ).mean(axis=0)
    with atomic_path(out) as tmp:
        write_recording(
            tmp,
            rec,
            compression=compression,
            overwrite=True,
            batch_frames=max(1, batch_bytes // max(1, c * h * w * 4)),
            attrs=extra,
            progress=progress,
        )
    return os.fspath(out)


def cmd_convert(args: argparse.Namespace) -> int:

    check_outputs({"-o": args.output}, inputs=[args.recording])
    with open_input(args) as rec:
        if not args.quiet:
            print(f"qogi convert: {rec}", file=sys.stderr)
            if getattr(rec, "scene_origin", None):
                print("qogi convert: scene: " + "; ".join(origin_lines(rec)), file=sys.stderr)
            for wmsg in getattr(rec, "warnings", None) or []:
                print(f"qogi convert: warning: {wmsg}", file=sys.stderr)
        bar = ProgressBar("convert ", enabled=not args.quiet)
        try:
            convert(rec, args.output, compression=args.compression, progress=bar)
        finally:
            bar.close()
    if not args.quiet:
        print(f"qogi convert: wrote {args.output}", file=sys.stderr)
    return 0


def add_commands(sub) -> None:

    c = sub.add_parser(
        "convert",
        help="convert a camera file (or recording) into a qogi recording (.h5)",
        description="Read a FLIR .seq/.csq/.jpg/.fff or Telops .hcc file (or a qogi recording) "
        "and write a qogi HDF5 recording, streaming in blocks and atomically (the "
        "output appears only when complete). Camera files do not hold everything: "
        "give --camera and, for .hcc, --distance and --ambient-temperature "
        "(`qogi info FILE` says what is needed). Each scene fact's origin is kept "
        "in the file.",
        epilog="example: qogi convert clip.seq -o clip.h5 --camera gf320 --distance 12",
    )
    c.add_argument("recording", metavar="IN", help="camera file or recording")
    c.add_argument("-o", "--output", required=True, metavar="OUT.h5", help="recording to write")
    c.add_argument("--compression", choices=["gzip", "lzf"], help="compress /frames (lossless)")
    c.add_argument("-q", "--quiet", action="store_true", help="no progress")
    add_scene_options(c)
    c.set_defaults(func=cmd_convert)
