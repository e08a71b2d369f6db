"""A PDF report of one quantified recording (``qogi quantify --report``).

Page 1: the header (recording, checksum, the recording's and the run's UTC
times, qogi version, the report's date, site, component, operator and
location when given: the audit record, qogi.audit), the scene (a
frame of the run with the control surfaces, their flux direction, the source
and the column-density overlay), the emission-rate time series with the mean
and its 90 % interval, and the table of surfaces and species. Page 2: the
uncertainty budget, the warnings, the settings (the full config, the unit and
the standard conditions) and the provenance. Drawn with matplotlib's PDF
backend; written atomically (qogi.files).
"""

from __future__ import annotations

import datetime
import math
import os
import textwrap

import numpy as np

from .._version import __version__
from ..audit import RECORD_SETTINGS, file_sha256
from ..files import PathLike, atomic_path
from ..io.hdf5 import open_recording
from ..pipeline.detection import DETECTION_SIGMA
from ..pipeline.settings import SETTINGS
from ..units import standard_conditions_text

__all__ = ["write_report", "file_sha256"]

_A4 = (8.27, 11.69)
_INK, _MUTED, _ACCENT = "#1b1f24", "#5b6470", "#0b5394"


def _fmt(x, nd: int = 4) -> str:
    if x is None or not math.isfinite(float(x)):
        return "-"
    return f"{float(x):.{nd}g}"


def _scene_frame(result, recording):
    """(image, label, overlay or None, origin) of the frame the report shows:
    a kept-maps frame near the middle of the run (with its column overlay),
    else the run's middle frame."""
    overlay, origin = None, (0, 0)
    frames = result.map_frames
    if frames:
        f = frames[len(frames) // 2]
        m = result.maps(f)
        cols = m["column_density_kg_m2"]
        overlay = next(iter(cols.values())) if cols else None
        origin = m.get("origin", (0, 0))
    else:
        cfg = result.config
        a, b = cfg.frames if getattr(cfg, "frames", None) else (0, recording.n_frames)
        f = (a + min(b, recording.n_frames)) // 2
    img = None
    if recording is not None:
        quantity = "radiometric_temperature"
        try:
            img = np.asarray(recording.frame(f, quantity=quantity))[0]
            label = "radiometric temperature [K]"
        except ValueError:
            img = np.asarray(recording.frame(f, quantity="radiance"))[0]
            label = "radiance [W/(m2 sr)]"
    return img, f, label if img is not None else "", overlay, origin


def _operating_rows(result):
    """Per surface and species, where in the operating envelope the rate was
    measured and the probability of detection there
    (``SpeciesRate.operating_point``)."""
    u = result.units
    rows = []
    for s in result.surfaces:
        for sp, r in s.species.items():
            op = r.operating_point
            if not op:
                continue

            def rate(v, r=r):
                return "-" if v is None else _fmt(r.in_units(v, u), 3)

            def num(v, fmt):
                return "-" if v is None else format(v, fmt)

            rows.append(
                [
                    s.surface.name,
                    sp,
                    num(op.get("delta_T_K"), "+.1f"),
                    num(op.get("distance_m"), ".3g"),
                    num(op.get("speed_m_s"), ".2g"),
                    num(op.get("snr"), ".3g"),
                    "-"
                    if op.get("expected_error") is None
                    else f"{100 * op['expected_error']:+.0f} %",
                    f"{rate(op.get('pod_50_kg_h'))} / {rate(op.get('pod_90_kg_h'))}",
                    "-" if op.get("pod_at_mean") is None else f"{100 * op['pod_at_mean']:.0f} %",
                ]
            )
    return rows


def _page_detectability(fig, result, sha):
    """Page 3: where the scene sits in the operating envelope (per rate: the
    temperature difference, distance, speed, signal-to-noise, the error
    model's expected error and the probability of detection there), and
    where in the frame the camera can see the gas: the minimum-detectable
    column map of each species with the surfaces."""
    _header(fig, result, sha, " (detectability)")
    y = 0.875
    ops = _operating_rows(result)
    if ops:
        fig.text(
            0.06,
            y + 0.01,
            f"Operating point and probability of detection [{result.units}]",
            fontsize=9,
            fontweight="bold",
            color=_INK,
        )
        h = 0.024 * (len(ops) + 1.6)
        ax = fig.add_axes((0.06, y - h, 0.88, h))
        _table(
            ax,
            [
                "surface",
                "species",
                "gas - bg\n[K]",
                "distance\n[m]",
                "speed\n[m/s]",
                "signal /\nlimit",
                "expected\nerror",
                "detected 50 / 90 %\nof the time at",
                "PoD at\nthe mean",
            ],
            ops,
            col_widths=[0.17, 0.08, 0.08, 0.09, 0.08, 0.08, 0.09, 0.21, 0.12],
        )
        y -= h + 0.05
    species = result.min_detectable_column_species
    h = min(0.36, (y - 0.12) / max(1, len(species)) - 0.05)
    for sp in species:
        fig.text(
            0.06, y, f"Minimum-detectable column: {sp}", fontsize=9, fontweight="bold", color=_INK
        )
        ax = fig.add_axes((0.06, y - 0.015 - h, 0.88, h))
        result.draw_min_detectable_column(ax, sp, fontsize=7.0)
        y -= h + 0.06
    fig.text(
        0.06,
        0.04,
        "Operating point: the gas-background temperature difference, distance and gas speed the "
        "run measured, the mean over its detection limit, the error the\nerror model fitted on "
        "the operating envelope expects, and the probability of detection (PoD) there: the rates "
        "a release is reported detected\n50 and 90 % of the time at, and the PoD of a release "
        "equal to the mean read ('-': not stated, e.g. the speed was not measured).\n"
        "Minimum-detectable column: per pixel, (k + z) times the noise-equivalent column at the "
        "pixel's own background "
        "temperature (the gas-free side of the frames' spread),\ngas at the run's temperature: "
        "a plume thinner than this there is seen in fewer than 95 % of frames "
        "(qogi.pipeline.detection).\nWhere gas sits in every frame the map is the gas-filled "
        "pixel's (an upper bound).",
        fontsize=6.5,
        color=_MUTED,
        va="bottom",
    )
    return fig


def _draw_scene(ax, result, recording):
    img, f, label, overlay, (ox, oy) = _scene_frame(result, recording)
    if img is None:
        ax.text(0.5, 0.5, "recording not available", ha="center", va="center", color=_MUTED)
        ax.set_axis_off()
        return
    lo, hi = np.percentile(img, [1, 99.5])
    ax.imshow(img, cmap="gray", vmin=lo, vmax=hi, interpolation="nearest")
    if overlay is not None and np.nanmax(overlay) > 0:
        h, w = overlay.shape
        show = np.ma.masked_less_equal(overlay, 0.05 * np.nanmax(overlay))
        im = ax.imshow(
            show * 1e3,
            cmap="inferno",
            alpha=0.75,
            interpolation="nearest",
            extent=(ox - 0.5, ox + w - 0.5, oy + h - 0.5, oy - 0.5),
        )
        cb = ax.figure.colorbar(im, ax=ax, fraction=0.035, pad=0.02)
        cb.set_label("column density [g/m2]", fontsize=7)
        cb.ax.tick_params(labelsize=6)
    for k, s in enumerate(result.surfaces):
        p = np.asarray(s.surface.points)
        color = f"C{k % 10}"
        ax.plot(p[:, 0], p[:, 1], "-", color=color, lw=2)
        xy, n, _ = s.surface.samples(step_px=max(1.0, s.surface.length_px / 2))
        mid, nm = xy[len(xy) // 2], n[len(n) // 2]
        arrow = 0.06 * max(img.shape)
        ax.annotate(
            "",
            xy=(mid[0] + arrow * nm[0], mid[1] + arrow * nm[1]),
            xytext=tuple(mid),
            arrowprops=dict(arrowstyle="-|>", color=color, lw=1.5),
        )
        end = p[np.argmax(p[:, 0])]
        ax.text(
            end[0] + 4,
            end[1],
            s.surface.name,
            color=color,
            fontsize=7,
            ha="left",
            va="center",
            fontweight="bold",
            bbox=dict(boxstyle="round,pad=0.15", fc="white", ec="none", alpha=0.7),
        )
    src = getattr(result.config, "source", None)
    if src is not None:
        ax.plot([src[0]], [src[1]], marker="x", color="#ff4040", ms=8, mew=2)
    ax.set_xlim(-0.5, img.shape[1] - 0.5)
    ax.set_ylim(img.shape[0] - 0.5, -0.5)
    ax.set_title(
        f"frame {f}: {label}; surfaces (arrow: positive flux), source x", fontsize=7.5, color=_MUTED
    )
    ax.tick_params(labelsize=6)


def _draw_rates(ax, result):
    unit = result.units
    for k, s in enumerate(result.surfaces):
        for j, (sp, r) in enumerate(s.species.items()):
            color = f"C{k % 10}"
            ls = ("-", "--", ":", "-.")[j % 4]
            y = r.in_units(r.rate_kg_h, unit)
            ax.plot(
                r.time_s,
                y,
                color=color,
                lw=0.7,
                ls=ls,
                alpha=0.85,
                label=f"{s.surface.name} {sp}: {r.text(unit)}",
            )
            if len(r.time_s) and math.isfinite(r.mean_kg_h):
                lo, hi = (r.in_units(v, unit) for v in r.ci90_kg_h)
                ax.axhline(r.in_units(r.mean_kg_h, unit), color=color, lw=1.4, ls=ls)
                ax.axhspan(lo, hi, color=color, alpha=0.12, lw=0)
            if r.truth_kg_h is not None:
                ax.axhline(r.in_units(r.truth_kg_h, unit), color="k", lw=1.0, ls="--")
    ax.set_xlabel("time [s]", fontsize=8)
    ax.set_ylabel(f"emission rate [{unit}]", fontsize=8)
    ax.tick_params(labelsize=7)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=6.5, loc="best", framealpha=0.85)
    ax.set_title(
        "emission rate per frame (lines: mean; bands: 90 % interval; dashed black: "
        "truth, synthetic recordings)",
        fontsize=7.5,
        color=_MUTED,
    )


def _table(ax, header, rows, col_widths=None, font=7.0):
    ax.set_axis_off()
    if not rows:
        ax.text(0, 0.5, "none", fontsize=font, color=_MUTED)
        return
    # Pinned to the axes' width, rows of a fixed height (0.024 of the page).
    row_h = 0.024 / ax.get_position().height
    h = min(1.0, row_h * (len(rows) + 1))
    t = ax.table(
        cellText=rows,
        colLabels=header,
        cellLoc="left",
        colLoc="left",
        colWidths=col_widths,
        bbox=(0.0, 1.0 - h, 1.0, h),
    )
    t.auto_set_font_size(False)
    t.set_fontsize(font)
    for (r, _c), cell in t.get_celld().items():
        cell.set_edgecolor("#c8ced6")
        cell.set_linewidth(0.5)
        if r == 0:
            cell.set_facecolor("#e8eef6")
            cell.set_text_props(fontweight="bold", color=_INK)


def _rate_rows(result):
    u = result.units
    rows = []
    for s in result.surfaces:
        for sp, r in s.species.items():
            lo, hi = (r.in_units(v, u) for v in r.ci90_kg_h)
            dl = r.detection_limit_kg_h
            shown = "not detected" if r.detected is False else _fmt(r.in_units(r.mean_kg_h, u))
            rows.append(
                [
                    s.surface.name,
                    sp,
                    shown,
                    f"{_fmt(lo)} .. {_fmt(hi)}",
                    "-"
                    if dl is None
                    else f"< {_fmt(r.in_units(r.upper_limit_kg_h, u), 3)}"
                    if r.upper_limit_kg_h is not None
                    else _fmt(r.in_units(dl, u), 3),
                    str(r.n_frames),
                    r.dominant_uncertainty,
                    "-"
                    if r.truth_kg_h is None
                    else f"{_fmt(r.in_units(r.truth_kg_h, u))} ({100 * r.error_vs_truth:+.1f} %)",
                ]
            )
    return rows


def _error_model_note(result) -> str:
    """A line on the intervals the error model calibrated (qogi.pipeline.error_model)
    and the error it expects on each, or nothing when it calibrated none."""
    parts = [
        f"{s.surface.name} {sp} {100 * r.error_model['expected_error']:+.0f} %"
        for s in result.surfaces
        for sp, r in s.species.items()
        if r.error_model
    ]
    if not parts:
        return ""
    return (
        "\nIntervals of detected rates calibrated by the error model fitted on the "
        "operating envelope; the error it expects (rate / truth - 1): " + ", ".join(parts)
    )


def _header(fig, result, sha, title_suffix=""):

    audit = result.audit
    version = audit.get("qogi_version") or __version__
    name = os.path.basename(str(result.recording_path))
    fig.text(
        0.06,
        0.970,
        f"qogi emission-rate report{title_suffix}",
        fontsize=15,
        fontweight="bold",
        color=_ACCENT,
    )
    fig.text(0.06, 0.952, f"recording {name}", fontsize=9, color=_INK)
    fig.text(
        0.06,
        0.940,
        f"SHA-256 {sha or 'unavailable'}",
        fontsize=6.5,
        color=_MUTED,
        family="monospace",
    )
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    fig.text(0.94, 0.970, f"qogi {version}", fontsize=9, ha="right", color=_INK)
    fig.text(0.94, 0.952, f"report {when}", fontsize=8, ha="right", color=_MUTED)
    times = (
        f"recorded {audit.get('recording_time_utc') or 'unknown'} (UTC); run "
        f"{audit.get('run_started_utc') or 'unknown'} .. {audit.get('run_finished_utc') or '-'}"
    )
    who = "; ".join(f"{k} {audit[k]}" for k in RECORD_SETTINGS if audit.get(k))
    fig.text(0.06, 0.929, times, fontsize=6.5, color=_MUTED)
    if who:
        fig.text(0.06, 0.918, who[:150], fontsize=6.5, color=_INK)
    status = "complete" if result.complete else "PARTIAL (cancelled or interrupted)"
    fig.text(
        0.94,
        0.940,
        f"run {status}",
        fontsize=7,
        ha="right",
        color=_MUTED if result.complete else "#b00020",
    )
    fig.add_artist(_hline(fig, 0.913))


def _hline(fig, y):
    from matplotlib.lines import Line2D

    return Line2D([0.06, 0.94], [y, y], transform=fig.transFigure, color=_ACCENT, lw=1.0)


def _wrap(lines, width=118):
    out = []
    for line in lines:
        out += textwrap.wrap(line, width, subsequent_indent="    ") or [""]
    return out


def _page_two(fig, result, sha):

    _header(fig, result, sha, " (continued)")
    u = result.units
    ax = fig.add_axes((0.06, 0.60, 0.88, 0.275))
    fig.text(
        0.06,
        0.895,
        "Uncertainty budget (1 sigma each; 90 % interval: relative terms as a log-normal factor, "
        "temporal and column noise added)",
        fontsize=9,
        fontweight="bold",
        color=_INK,
    )
    terms = sorted(
        {t for s in result.surfaces for r in s.species.values() for t in r.uncertainty_terms_kg_h}
    )
    rows = []
    for s in result.surfaces:
        for sp, r in s.species.items():
            tv = [_fmt(r.in_units(r.uncertainty_terms_kg_h.get(t, math.nan), u), 3) for t in terms]
            rows.append(
                [s.surface.name, sp]
                + tv
                + [_fmt(r.in_units(r.sigma_kg_h, u), 3), r.dominant_uncertainty]
            )
    _table(
        ax,
        ["surface", "species"] + [f"{t}\n[{u}]" for t in terms] + [f"total\n[{u}]", "dominant"],
        rows,
    )
    y = 0.875 - 0.024 * (len(rows) + 1) - 0.04
    drows = []
    for s in result.surfaces:
        for sp, r in s.species.items():
            d = r.detection or {}
            if r.detection_limit_kg_h is None or not d:
                continue
            nec = d.get("noise_equivalent_column_kg_m2")
            drows.append(
                [
                    s.surface.name,
                    sp,
                    _fmt(r.in_units(r.detection_limit_kg_h, u), 3),
                    "-" if nec is None else f"{nec * 1e3:.3g}",
                    _fmt(d.get("velocity_m_s"), 3),
                    _fmt(100 * d.get("width_m", math.nan), 3),
                    str(d.get("width_from", "")).split(" (")[0],
                    "yes" if r.detected else "no",
                ]
            )
    if drows:
        fig.text(
            0.06,
            y,
            f"Detection limit = (k + z) x NEC x velocity x width  (k = "
            f"{DETECTION_SIGMA:g}; z: seen in 95 % of frames)",
            fontsize=9,
            fontweight="bold",
            color=_INK,
        )
        h = 0.024 * (len(drows) + 1) + 0.005
        ax = fig.add_axes((0.06, y - 0.012 - h, 0.88, h))
        _table(
            ax,
            [
                "surface",
                "species",
                f"limit\n[{u}]",
                "noise-equivalent\ncolumn [g/m2]",
                "velocity\n[m/s]",
                "width\n[cm]",
                "width from",
                "detected",
            ],
            drows,
            col_widths=[0.17, 0.08, 0.1, 0.14, 0.1, 0.09, 0.22, 0.1],
        )
        y -= 0.012 + h + 0.04
    fig.text(
        0.06, y, f"Warnings ({len(result.warnings)})", fontsize=9, fontweight="bold", color=_INK
    )
    wl = _wrap([f"- {w}" for w in result.warnings] or ["none"], 120)
    fig.text(0.06, y - 0.012, "\n".join(wl[:14]), fontsize=7, va="top", color=_INK)
    y -= 0.03 + 0.0115 * min(len(wl), 14)
    fig.text(0.06, y, "Settings", fontsize=9, fontweight="bold", color=_INK)
    cfg = result.config.to_dict() if hasattr(result.config, "to_dict") else dict(result.config)
    lines = [f"{k} = {v}" for k, v in _settings_used(cfg, result.info).items()]
    lines += [
        f"reporting unit = {u}",
        f"volumes at standard conditions: {standard_conditions_text(result.standard_conditions)}",
        "pixels: " + ", ".join(f"{k} {v}" for k, v in result.pixel_status.items()),
    ]
    info = {k: v for k, v in result.info.items() if isinstance(v, (int, float, str))}
    lines += [f"info: {k} = {_fmt(v, 5) if isinstance(v, float) else v}" for k, v in info.items()]
    wl = _wrap(lines, 112)
    fig.text(
        0.06, y - 0.012, "\n".join(wl[:60]), fontsize=6.5, va="top", family="monospace", color=_INK
    )
    fig.text(
        0.06,
        0.03,
        f"Replay: qogi quantify {os.path.basename(str(result.recording_path))} "
        "--config <result.json> (the result JSON embeds these settings and surfaces).",
        fontsize=6.5,
        color=_MUTED,
    )


def write_report(result, path: PathLike, recording=None) -> str:
    """Write the PDF report of ``result`` to ``path`` (atomically); returns the path.

    ``recording`` (a qogi.Recording) gives the scene's frame; None opens
    ``result.recording_path`` (the page says so if it cannot be read).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt
    from matplotlib.backends.backend_pdf import PdfPages

    if recording is None:
        try:
            recording = open_recording(result.recording_path)
        except (OSError, ValueError):
            recording = None
    # The checksum the run stamped (the file as quantified), else the file's now.
    sha = result.audit.get("recording_sha256") or file_sha256(result.recording_path)
    u = result.units

    with plt.rc_context(
        {
            "font.family": "DejaVu Sans",
            "axes.edgecolor": "#8a939e",
            "axes.linewidth": 0.6,
            "pdf.fonttype": 42,
        }
    ):
        page1 = plt.figure(figsize=_A4)
        _header(page1, result, sha)
        page1.text(0.06, 0.899, "Scene", fontsize=9, fontweight="bold", color=_INK)
        ax = page1.add_axes((0.06, 0.57, 0.88, 0.32))
        _draw_scene(ax, result, recording)
        page1.text(0.06, 0.545, "Emission rate", fontsize=9, fontweight="bold", color=_INK)
        ax = page1.add_axes((0.10, 0.32, 0.84, 0.21))
        _draw_rates(ax, result)
        page1.text(
            0.06, 0.265, f"Surfaces and species [{u}]", fontsize=9, fontweight="bold", color=_INK
        )
        ax = page1.add_axes((0.06, 0.08, 0.88, 0.175))
        _table(
            ax,
            [
                "surface",
                "species",
                "mean",
                "90 % interval",
                "detection\nlimit",
                "frames",
                "dominant\nuncertainty",
                "truth (error)",
            ],
            _rate_rows(result),
            col_widths=[0.19, 0.08, 0.09, 0.16, 0.1, 0.07, 0.14, 0.17],
        )
        conf = next(
            (
                r.detection.get("confidence")
                for s in result.surfaces
                for r in s.species.values()
                if r.detection
            ),
            None,
        )
        page1.text(
            0.06,
            0.04,
            "Flux counts positive along each surface's arrow (left-hand "
            "normal from its first point to its last, x right, y down).\nDetection "
            "limit: the smallest rate seen in "
            f"{'95' if conf is None else f'{100 * conf:.0f}'} % of frames "
            "(qogi.pipeline.detection); "
            "below it the rate reads 'not detected'; '-': not computed."
            + _error_model_note(result),
            fontsize=6.5,
            color=_MUTED,
            va="bottom",
        )
        page2 = plt.figure(figsize=_A4)
        _page_two(page2, result, sha)
        pages = [page1, page2]
        if result.min_detectable_column_species or _operating_rows(result):
            pages.append(_page_detectability(plt.figure(figsize=_A4), result, sha))
        with atomic_path(path, suffix=".pdf") as tmp:
            with PdfPages(tmp) as pdf:
                d = pdf.infodict()
                d["Title"] = (
                    f"qogi emission-rate report: {os.path.basename(str(result.recording_path))}"
                )
                d["Creator"] = "qogi"
                for page in pages:
                    pdf.savefig(page)
        for page in pages:
            plt.close(page)
    return os.fspath(path)


def _settings_used(cfg: dict, info: dict) -> dict:
    """The run's settings as used: the config as given, each scene fact not
    given shown with the recording's value (``info["from_recording"]``) or
    its fallback (qogi.pipeline.settings)."""

    taken = info.get("from_recording") or {}
    out = {}
    for k, given in cfg.items():
        used = given
        if given is None and k in taken:
            used = f"{taken[k]} (the recording's)"
        elif given is None and k in SETTINGS and SETTINGS[k].fallback is not None:
            f = SETTINGS[k].fallback
            used = list(f) if isinstance(f, tuple) else f
        out[k] = used
    return out
