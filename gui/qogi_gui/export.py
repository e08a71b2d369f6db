"""Writing results out: CSV, JSON, plot PNGs, the current frame as PNG, a report.

CSV, JSON and plots are the pipeline's own writers (``Result.to_csv``,
``Result.to_json``, ``Result.plot``), so a file exported from the viewer is
the same as one from ``qogi quantify``. The frame PNG is what the window
shows (colour-mapped frame, column-density overlay, surfaces with their flux
direction, background region); the report is short Markdown for people, or
the PDF of ``qogi quantify --report`` (``qogi.apps.report``).
"""

from __future__ import annotations

import datetime
import math
import os
from pathlib import Path
from typing import List, Optional, Sequence

import numpy as np

from .results import pixel_status_rows, rate_rows, standard_conditions_text
from .surfaces import RegionDraft, SurfaceDraft, flow_arrow

__all__ = [
    "check_writable",
    "write_frame_png",
    "write_plots",
    "write_report",
    "write_pdf_report",
    "ExportError",
]


class ExportError(ValueError):
    """A file could not be written; the message says which and why."""


def check_writable(path: os.PathLike) -> Path:
    """The path as a Path if its folder exists and is writable, else ExportError."""
    p = Path(os.fspath(path)).expanduser()
    if not str(p).strip() or p.name == "":
        raise ExportError("no file name given: choose where to save")
    if p.is_dir():
        raise ExportError(f"{p} is a folder: give a file name")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ExportError(f"cannot write {p}: the folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise ExportError(f"cannot write {p}: no permission to write in {folder}")
    return p


def _use_agg():
    """Plots are written to files only: never open a GUI backend from the viewer."""
    import matplotlib

    if matplotlib.get_backend().lower() != "agg":
        matplotlib.use("Agg", force=True)


def write_plots(result, path: os.PathLike, maps: bool = False) -> List[Path]:
    """The rate time-series plot (``result.plot(kind="rates")``) at ``path``,
    and with ``maps`` the maps plot beside it (``<stem>_maps.png``)."""
    p = check_writable(path)
    _use_agg()
    import matplotlib.pyplot as plt

    written = []
    for kind, target in (("rates", p), ("maps", p.with_name(p.stem + "_maps" + p.suffix))):
        if kind == "maps" and not maps:
            continue
        fig = result.plot(str(target), kind=kind)
        if fig is not None:
            plt.close(fig)
        if not target.exists():
            raise ExportError(f"the {kind} plot was not written to {target}")
        written.append(target)
    return written


def render_frame_rgb(
    rgba: np.ndarray,
    surfaces: Sequence[SurfaceDraft],
    region: Optional[RegionDraft] = None,
    zoom: int = 3,
    source=None,
) -> np.ndarray:
    """The shown frame (RGBA float (H, W, 4), overlay already blended) scaled
    up ``zoom`` times, with surfaces, their flux arrows and the background
    region drawn on it; uint8 RGB (H*zoom, W*zoom, 3)."""
    import cv2

    from .display import to_uint8_rgb

    rgb = to_uint8_rgb(rgba)
    img = np.ascontiguousarray(np.repeat(np.repeat(rgb, zoom, axis=0), zoom, axis=1))
    shift = 4
    k = float(1 << shift)

    def px(p):  # pixel coordinates (centres at integers) -> fixed-point screen position
        return (int(round((p[0] + 0.5) * zoom * k)), int(round((p[1] + 0.5) * zoom * k)))

    if region is not None:
        cv2.rectangle(
            img,
            px((region.x0 - 0.5, region.y0 - 0.5)),
            px((region.x1 - 0.5, region.y1 - 0.5)),
            (255, 255, 255),
            1,
            cv2.LINE_AA,
            shift,
        )
    for s in surfaces:
        if len(s.points) < 2:
            continue
        pts = np.array([px(p) for p in s.points], np.int32).reshape(-1, 1, 2)
        cv2.polylines(img, [pts], False, tuple(int(c) for c in s.colour), 2, cv2.LINE_AA, shift)
        arrow = flow_arrow(s.points, length=max(6.0, 0.04 * max(rgba.shape[:2])))
        if arrow is not None:
            cv2.arrowedLine(
                img,
                px(arrow[0]),
                px(arrow[1]),
                tuple(int(c) for c in s.colour),
                2,
                cv2.LINE_AA,
                shift,
                0.35,
            )
        x, y = s.points[0]
        cv2.putText(
            img,
            s.name,
            (int((x + 0.5) * zoom) + 4, int((y + 0.5) * zoom) - 6),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.5,
            tuple(int(c) for c in s.colour),
            1,
            cv2.LINE_AA,
        )
    if source is not None:
        cv2.drawMarker(
            img,
            (int((source[0] + 0.5) * zoom), int((source[1] + 0.5) * zoom)),
            (255, 60, 60),
            cv2.MARKER_CROSS,
            14,
            2,
        )
    return img


def write_frame_png(path: os.PathLike, rgb: np.ndarray) -> Path:
    """Write uint8 RGB (H, W, 3) as a PNG."""
    import cv2

    p = check_writable(path)
    if p.suffix.lower() != ".png":
        raise ExportError(f"{p}: the frame is written as PNG; use a .png file name")
    from qogi.files import atomic_path

    with atomic_path(p) as tmp:
        if not cv2.imwrite(str(tmp), np.ascontiguousarray(rgb[..., ::-1])):
            raise ExportError(f"could not write the image {p}")
    return p


def _fmt(x: float, nd: int = 3) -> str:
    if x is None or not math.isfinite(x):
        return "n/a"
    return f"{x:.{nd}g}"


def report_text(
    result,
    recording_summary: dict,
    surfaces: Sequence[SurfaceDraft],
    settings_kwargs: dict,
    files: Sequence[os.PathLike] = (),
) -> str:
    """A short Markdown report: recording, surfaces, settings, rates (with the
    truth when known), pixel status, the pipeline's own summary."""
    from qogi import __version__

    rs = recording_summary or {}
    cam, fr, sc = rs.get("camera", {}), rs.get("frames", {}), rs.get("scene", {})
    lines = [
        "# qogi emission-rate report",
        "",
        f"Written {datetime.datetime.now().isoformat(timespec='seconds')} by the qogi "
        f"viewer (qogi {__version__}).",
        "",
        "## Recording",
        "",
    ]
    lines.append(f"- file: `{rs.get('path', getattr(result, 'recording_path', ''))}`")
    lines.append(
        f"- camera: {cam.get('name', '?')}, {fr.get('C', '?')} channel(s) "
        f"({', '.join(c.get('name', '') for c in rs.get('channels', []))}), "
        f"ifov {_fmt(cam.get('ifov_rad', math.nan))} rad, "
        f"{_fmt(cam.get('frame_rate_hz', math.nan))} Hz"
    )
    lines.append(
        f"- frames: {fr.get('T', '?')} x {fr.get('W', '?')}x{fr.get('H', '?')} px, "
        f"{_fmt(fr.get('duration_s', math.nan))} s, stored as {fr.get('quantity', '?')}"
    )
    lines.append(
        f"- scene: distance {_fmt(sc.get('distance_m', math.nan))} m, ambient "
        f"{_fmt(sc.get('ambient_temperature_K', math.nan), 5)} K, pressure "
        f"{_fmt(sc.get('pressure_Pa', math.nan), 6)} Pa"
    )
    lines += [
        "",
        "## Control surfaces",
        "",
        "Flux counts positive along each surface's left-hand normal walking from its "
        "first point to its last (x right, y down).",
        "",
    ]
    for s in surfaces:
        pts = ", ".join(f"({x:.1f}, {y:.1f})" for x, y in s.points)
        lines.append(f"- {s.name}: {pts}")
    lines += ["", "## Settings", ""]
    for k, v in settings_kwargs.items():
        lines.append(f"- {k}: {v}")
    lines += [
        "",
        "## Emission rates",
        "",
        "| surface | species | mean [kg/h] | 90% interval [kg/h] | [g/h] | [SLPM] | truth "
        "[kg/h] | error | frames (valid) | pixels (median) | dominant uncertainty | "
        "detection limit [kg/h] |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rate_rows(result):
        err = r.error_pct
        lines.append(
            f"| {r.surface} | {r.species} | {_fmt(r.mean_kg_h, 4)} | {_fmt(r.ci90_kg_h[0], 4)} "
            f"to {_fmt(r.ci90_kg_h[1], 4)} | {_fmt(r.mean_g_h, 4)} | {_fmt(r.mean_slpm, 4)} | "
            f"{_fmt(r.truth_kg_h, 4) if r.truth_kg_h is not None else '-'} | "
            f"{f'{err:+.1f} %' if err is not None else '-'} | {r.n_frames} "
            f"({r.n_frames_valid}) | {_fmt(r.pixels_median, 4)} | {r.dominant_uncertainty} | "
            f"{r.detection_text} |"
        )
    sc_std = standard_conditions_text(result)
    if sc_std:
        lines += ["", f"SLPM at standard conditions: {sc_std}."]
    status = pixel_status_rows(result)
    if status:
        lines += ["", "## Pixels", "", "| status | pixels | share |", "|---|---|---|"]
        lines += [f"| {s} | {n} | {p:.1f} % |" for s, n, p in status]
    summary = result.summary() if hasattr(result, "summary") else ""
    if summary:
        lines += ["", "## Pipeline summary", "", "```", str(summary).rstrip(), "```"]
    if files:
        lines += ["", "## Files", ""] + [f"- `{Path(f).name}`" for f in files]
    return "\n".join(lines) + "\n"


def write_pdf_report(result, path: os.PathLike, recording=None) -> Path:
    """The one-recording PDF report (``qogi.apps.report.write_report``, as
    ``qogi quantify --report``): scene, rates, table, budget, warnings, settings."""
    from qogi.apps.report import write_report as write_pdf

    p = check_writable(path)
    if p.suffix.lower() != ".pdf":
        raise ExportError(f"{p}: the report is written as PDF; use a .pdf file name")
    _use_agg()
    write_pdf(result, p, recording=recording)
    return p


def write_report(path: os.PathLike, text: str) -> Path:
    from qogi.files import atomic_open

    p = check_writable(path)
    with atomic_open(p, "w", encoding="utf-8") as fh:
        fh.write(text)
    return p
