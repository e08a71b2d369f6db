"""Command-line options shared by every command that opens a recording or a
camera file (``quantify``, ``info``, ``convert``, ``gui``): the scene facts a
camera file does not hold."""

from __future__ import annotations

import argparse

from ..io.open import file_kind, open_recording, scene_needs
from ..io.telops import CALIBRATION_MODES, HccFile
from ..physics.presets import camera_preset_names
from ..pipeline.settings import arg_type
from .info import flir_info, format_flir_info, format_recording_info, info_json, recording_info


def add_scene_options(p: argparse.ArgumentParser, distance: bool = True) -> None:
    """--camera, --distance, --ambient-temperature, --pressure."""

    g = p.add_argument_group(
        "camera files (FLIR .seq/.csq/.jpg/.fff, Telops .hcc)",
        "Scene facts a camera file does not hold; qogi refuses to guess them.",
    )
    g.add_argument(
        "--camera",
        metavar="|".join(camera_preset_names()) + "|RESPONSE.csv",
        help="the camera's spectral response: a preset or a CSV (wavenumber_cm1 or "
        "wavelength_um, response); required for camera files",
    )
    if distance:
        g.add_argument(
            "--distance",
            type=arg_type("distance_m"),
            metavar="M",
            help="camera-to-plume distance [m] (required for .hcc; FLIR files hold "
            "an object distance, flagged when it is FLIR's default 1 m)",
        )
    g.add_argument(
        "--ambient-temperature",
        type=arg_type("ambient_temperature_K"),
        metavar="K",
        help="ambient air temperature [K] (required for .hcc; FLIR files hold one)",
    )
    g.add_argument(
        "--pressure",
        type=arg_type("pressure_Pa"),
        metavar="PA",
        help="ambient pressure [Pa] (default 101325, flagged)",
    )


def open_input(args: argparse.Namespace, **kw):
    """Open ``args.recording`` (or ``args.path``) with the scene options."""

    path = getattr(args, "recording", None) or args.path
    return open_recording(
        path,
        camera=args.camera,
        distance_m=getattr(args, "distance", None),
        ambient_temperature_K=args.ambient_temperature,
        pressure_Pa=args.pressure,
        **kw,
    )


def origin_lines(rec) -> list:
    """One line per scene fact with where it came from."""
    origin = getattr(rec, "scene_origin", None) or {}
    sc = rec.scene
    out = []
    for key, label, value in (
        ("distance_m", "distance", f"{sc.distance_m:g} m"),
        ("ambient_temperature_K", "ambient temperature", f"{sc.ambient_temperature_K:g} K"),
        ("pressure_Pa", "pressure", f"{sc.pressure_Pa:g} Pa"),
        ("ifov_rad", "IFOV", f"{rec.camera.ifov_rad * 1e3:.4g} mrad"),
        ("time_s", "frame times", f"{rec.n_frames} frames"),
    ):
        if key in origin:
            out.append(f"{label} {value} ({origin[key]})")
    return out


# --------------------------------------------------------------------------- qogi info


def hcc_info(path) -> dict:
    """What a Telops .hcc file holds: size, version, calibration mode, frame
    times, filter positions, scaling range, first-frame statistics."""
    import numpy as np

    with HccFile(path) as h:
        f = h.fields()
        first = h.values(0)[0]
        n, w, hh, ver, trailing = h.n_frames, h.width, h.height, h.version, h.trailing_bytes
    t = f["time_s"]
    finite = first[np.isfinite(first)]
    modes = sorted(
        {CALIBRATION_MODES.get(int(m), (f"mode {m}",))[0] for m in f["CalibrationMode"].tolist()}
    )
    return {
        "path": str(path),
        "kind": "telops",
        "n_frames": int(n),
        "width": int(w),
        "height": int(hh),
        "version": f"{ver[0]}.{ver[1]}",
        "calibration_modes": modes,
        "trailing_bytes": int(trailing),
        "time_first_posix_s": float(t[0]),
        "time_span_s": float(t[-1] - t[0]),
        "acquisition_frame_rate_hz": float(f["AcquisitionFrameRate"][0]) / 1000.0,
        "exposure_time_us": sorted({float(e) / 100.0 for e in f["ExposureTime"].tolist()}),
        "filter_wheel": bool(f["FWMode"].any()),
        "filter_positions": sorted(set(f["FWPosition"].tolist())),
        "data_offset_range": [float(f["DataOffset"].min()), float(f["DataOffset"].max())],
        "data_exp_range": [int(f["DataExp"].min()), int(f["DataExp"].max())],
        "first_frame": {
            "min": float(finite.min()) if finite.size else None,
            "mean": float(finite.mean()) if finite.size else None,
            "max": float(finite.max()) if finite.size else None,
            "n_bad_pixels": int(first.size - finite.size),
        },
    }


def format_hcc_info(info: dict) -> str:
    ff = info["first_frame"]
    wheel = (
        f"filter wheel, positions {info['filter_positions']}"
        if info["filter_wheel"]
        else "fixed filter"
    )
    return "\n".join(
        [
            f"Telops file {info['path']}  (hcc v{info['version']}, {info['n_frames']} frames, "
            f"{info['width']}x{info['height']}, {', '.join(info['calibration_modes'])})",
            f"time       span {info['time_span_s']:.6g} s "
            f"from POSIX {info['time_first_posix_s']:.7f} s; "
            f"acquisition {info['acquisition_frame_rate_hz']:g} Hz, exposure "
            f"{', '.join(f'{e:g}' for e in info['exposure_time_us'])} us",
            f"filter     {wheel}",
            f"scaling    per frame: DataOffset {info['data_offset_range'][0]:g}..."
            f"{info['data_offset_range'][1]:g}, DataExp {info['data_exp_range'][0]}..."
            f"{info['data_exp_range'][1]}",
            f"frame 0    min {ff['min']}, mean {ff['mean']}, max {ff['max']}, "
            f"{ff['n_bad_pixels']} bad pixels",
        ]
        + (
            [
                f"warning: {info['trailing_bytes']} bytes after the last whole frame: "
                "a cut-off last frame is left out"
            ]
            if info["trailing_bytes"]
            else []
        )
    )


def format_needs(needs: dict) -> str:
    """What opening (quantify, convert) this file needs, and what it holds."""
    flags = {
        "camera": "--camera gf320|fast-m150|response.csv",
        "distance_m": "--distance M",
        "ambient_temperature_K": "--ambient-temperature K",
    }
    lines = []
    if needs["needs"]:
        lines.append("to quantify or convert: give " + " ".join(flags[k] for k in needs["needs"]))
    for k in needs["defaults"]:
        lines.append(
            f"  the file's {k} = {needs['holds'][k]:g} is FLIR's factory default: "
            f"give {flags[k]} (it is used otherwise, with a warning)"
        )
    held = {k: v for k, v in needs["holds"].items() if k in ("distance_m", "ambient_temperature_K")}
    if held:
        lines.append(
            "held by the file (used unless given): "
            + ", ".join(f"{k} {v:g}" for k, v in held.items())
        )
    if needs["holds"].get("band_um"):
        lines.append(
            f"  calibrated band near {needs['holds']['band_um']:.2f} um: the camera "
            "given must see this band"
        )
    lines.append("pressure: not in the file; 101325 Pa unless --pressure (flagged)")
    return "\n".join(lines)


def cmd_info_camera(args) -> int:
    """``qogi info`` for a camera file: what it holds, what a conversion needs,
    and with --camera the recording it opens as."""
    import sys

    kind = file_kind(args.path)
    info = flir_info(args.path) if kind == "flir" else hcc_info(args.path)
    text = format_flir_info(info) if kind == "flir" else format_hcc_info(info)
    needs = scene_needs(args.path)
    info["needs"] = needs
    rec_text = ""
    if args.camera:
        with open_input(args) as rec:
            rinfo = recording_info(rec)
            rinfo["scene_origin"] = dict(getattr(rec, "scene_origin", {}))
            rinfo["warnings"] = [w.to_dict() for w in getattr(rec, "warnings", [])]
            info["recording"] = rinfo
            rec_text = (
                "\nas a recording:\n"
                + format_recording_info(rinfo)
                + "\nscene origin: "
                + "; ".join(origin_lines(rec))
                + "".join(f"\nwarning: {w}" for w in getattr(rec, "warnings", []))
            )
    if args.json:
        print(info_json(info))
    else:
        print(text + "\n" + format_needs(needs) + rec_text)
    sys.stdout.flush()
    return 0
