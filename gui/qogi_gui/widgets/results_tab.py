"""The Results tab (the side-by-side table, the comparison chart, the
pixel-status summary, the warnings, the exports) and the emission-rate time
series under the image.

Everything shown comes from :mod:`qogi_gui.results` (plain functions over a
``qogi.Result``); this module only lays it out.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import dearpygui.dearpygui as dpg

from .. import results
from ..surfaces import SURFACE_COLOURS
from .panel import Panel
from .theme import GREY, YELLOW

__all__ = ["ResultsTab", "build_results_panel", "build_rates_plot"]


def _fmt(x, nd=4):
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.{nd}g}"


def _colour_of(app, name):
    for s in app.vm.run.result_surfaces:
        if s.name == name:
            return s.colour
    return SURFACE_COLOURS[0]


def build_results_panel(app, parent) -> None:
    run = app.vm.run
    dpg.delete_item(parent, children_only=True)
    res = run.result
    if res is None:
        dpg.add_text(
            "No result yet: draw a surface, check the Analysis tab and run.",
            parent=parent,
            color=GREY,
            wrap=420,
        )
        return
    if run.result_partial:
        dpg.add_text(
            "Partial result: the run was cancelled; these numbers rest on the frames "
            "finished before that.",
            parent=parent,
            color=YELLOW,
            wrap=420,
        )
    rows = results.rate_rows(res)
    surfaces = list(dict.fromkeys(r.surface for r in rows))
    species = list(dict.fromkeys(r.species for r in rows))
    by = {(r.surface, r.species): r for r in rows}

    dpg.add_text("Emission rate per surface (side by side)", parent=parent)
    with dpg.table(
        parent=parent,
        header_row=True,
        borders_innerV=True,
        borders_outerH=True,
        policy=dpg.mvTable_SizingStretchProp,
        row_background=True,
    ):
        dpg.add_table_column(label="", init_width_or_weight=1.3)
        for s in surfaces:
            dpg.add_table_column(label=s, init_width_or_weight=1.0)
        for sp in species:
            lines = (
                [
                    (f"{sp} mean [kg/h]", lambda r: _fmt(r.mean_kg_h)),
                    ("90% low [kg/h]", lambda r: _fmt(r.ci90_kg_h[0])),
                    (
                        "90% high [kg/h]",
                        lambda r: (
                            "unbounded" if math.isinf(r.ci90_kg_h[1]) else _fmt(r.ci90_kg_h[1])
                        ),
                    ),
                    ("[g/h]", lambda r: _fmt(r.mean_g_h)),
                    ("[SLPM]", lambda r: _fmt(r.mean_slpm)),
                    (
                        "truth [kg/h]",
                        lambda r: _fmt(r.truth_kg_h) if r.truth_kg_h is not None else "-",
                    ),
                    (
                        "error vs truth",
                        lambda r: f"{r.error_pct:+.1f} %" if r.error_pct is not None else "-",
                    ),
                    ("frames (valid)", lambda r: f"{r.n_frames} ({r.n_frames_valid})"),
                    ("pixels (median)", lambda r: _fmt(r.pixels_median, 4)),
                    ("dominant uncertainty", lambda r: r.dominant_uncertainty or "-"),
                    ("1 sigma [kg/h]", lambda r: ""),
                ]
                + [
                    (
                        f"  {term}",
                        lambda r, term=term: (
                            _fmt(r.uncertainty_terms_kg_h[term], 3)
                            if term in r.uncertainty_terms_kg_h
                            else "-"
                        ),
                    )
                    for term in results.uncertainty_terms(rows)
                ]
                + [
                    ("detection limit [kg/h]", lambda r: r.detection_text),
                ]
            )
            for label, fn in lines:
                with dpg.table_row():
                    dpg.add_text(label, color=GREY)
                    for s in surfaces:
                        r = by.get((s, sp))
                        dpg.add_text(
                            fn(r) if r is not None else "-",
                            color=(255, 255, 255)
                            if label.endswith("[kg/h]") and "mean" in label
                            else (220, 220, 220),
                        )
    if run.result_stale:
        dpg.add_text(
            "Surfaces or settings changed since this run: run again to update.",
            parent=parent,
            color=YELLOW,
            wrap=420,
        )
    warnings = results.warning_lines(res)
    if warnings:
        dpg.add_text(f"Warnings ({len(warnings)})", parent=parent, color=YELLOW)
        for line in warnings:
            dpg.add_text(line, parent=parent, color=YELLOW, wrap=420, bullet=True)
    std = results.standard_conditions_text(res)
    if std:
        dpg.add_text(f"SLPM at {std}", parent=parent, color=GREY, wrap=420)

    # Means with their 90% intervals, surfaces next to each other.
    with dpg.plot(parent=parent, height=190, width=-1, no_menus=True, no_box_select=True):
        dpg.add_plot_legend(location=dpg.mvPlot_Location_NorthWest)
        xa = dpg.add_plot_axis(dpg.mvXAxis, no_gridlines=True)
        ya = dpg.add_plot_axis(dpg.mvYAxis, label="mean [kg/h]")
        dpg.set_axis_ticks(xa, tuple((s, float(i)) for i, s in enumerate(surfaces)))
        width = 0.7 / max(1, len(species))
        for k, sp in enumerate(species):
            xs, ys, lo, hi = [], [], [], []
            for i, s in enumerate(surfaces):
                r = by.get((s, sp))
                if r is None or not math.isfinite(r.mean_kg_h):
                    continue
                xs.append(i + (k - (len(species) - 1) / 2) * width)
                ys.append(r.mean_kg_h)
                lo.append(
                    max(0.0, r.mean_kg_h - r.ci90_kg_h[0]) if math.isfinite(r.ci90_kg_h[0]) else 0.0
                )
                hi.append(
                    max(0.0, r.ci90_kg_h[1] - r.mean_kg_h) if math.isfinite(r.ci90_kg_h[1]) else 0.0
                )
            if xs:
                dpg.add_bar_series(xs, ys, weight=width * 0.9, label=sp, parent=ya)
                dpg.add_error_series(xs, ys, lo, hi, parent=ya)
            truth = next(
                (
                    by[(s, sp)].truth_kg_h
                    for s in surfaces
                    if (s, sp) in by and by[(s, sp)].truth_kg_h is not None
                ),
                None,
            )
            if truth is not None:  # a line across the bars (fitting the axis takes it in)
                t = dpg.add_line_series(
                    [-0.6, len(surfaces) - 0.4], [truth, truth], label=f"truth {sp}", parent=ya
                )
                dpg.bind_item_theme(t, app.themes["truth"])
        dpg.set_axis_limits(xa, -0.6, len(surfaces) - 0.4)
        dpg.fit_axis_data(ya)

    status = results.pixel_status_rows(res)
    if status:
        dpg.add_text("Pixels (all quantified frames)", parent=parent)
        with dpg.table(
            parent=parent,
            header_row=True,
            policy=dpg.mvTable_SizingStretchProp,
            borders_innerH=True,
        ):
            for label in ("status", "pixels", "share"):
                dpg.add_table_column(label=label)
            for name, n, pct in status:
                with dpg.table_row():
                    dpg.add_text(name)
                    dpg.add_text(f"{n:,}")
                    dpg.add_text(f"{pct:.1f} %")
    summary = res.summary() if hasattr(res, "summary") else ""
    if summary:
        with dpg.collapsing_header(label="Pipeline summary", parent=parent, default_open=False):
            dpg.add_text(str(summary), wrap=420)


def build_rates_plot(app, axis) -> None:
    """Emission rate per surface and species over time, with each mean and its
    90% interval as a band, and the truth when the recording has it."""
    dpg.delete_item(axis, children_only=True)
    res = app.vm.run.result
    if res is None:
        return
    truths = {}
    span = [math.inf, -math.inf]
    for ser in results.rate_series(res):
        t, y = ser["time_s"], ser["rate_kg_h"]
        if t.size == 0:
            continue
        span = [min(span[0], float(t[0])), max(span[1], float(t[-1]))]
        colour = _colour_of(app, ser["surface"])
        label = f"{ser['surface']} {ser['species']}"
        line = dpg.add_line_series(list(t), list(y), label=label, parent=axis)
        dpg.bind_item_theme(line, app.themes[("thin", colour)])
        lo, hi = ser["ci90_kg_h"]
        t0, t1 = float(t[0]), float(t[-1])
        if math.isfinite(lo) and math.isfinite(hi):
            band = dpg.add_shade_series(
                [t0, t1], [lo, lo], y2=[hi, hi], label=f"{label} 90% band", parent=axis
            )
            dpg.bind_item_theme(band, app.themes[("line", colour)])
        m = ser["mean_kg_h"]
        if math.isfinite(m):
            mean = dpg.add_line_series(
                [t0, t1], [m, m], label=f"{label} mean {m:.3g} kg/h", parent=axis
            )
            dpg.bind_item_theme(mean, app.themes[("selected", colour)])
        if ser["truth_kg_h"] is not None:
            truths[ser["species"]] = ser["truth_kg_h"]
    for sp, v in truths.items():  # a line over the run (fitting the axis takes it in)
        t = dpg.add_line_series(span, [v, v], label=f"truth {sp} {v:.3g} kg/h", parent=axis)
        dpg.bind_item_theme(t, app.themes["truth"])
    dpg.fit_axis_data("rates_x")
    dpg.fit_axis_data(axis)


class ResultsTab(Panel):
    """The Results tab and the rate time series under the image."""

    def build(self) -> None:
        dpg.add_group(tag="results_group")
        dpg.add_separator()
        self._build_exports()

    def build_rates_plot(self) -> None:
        """The emission-rate plot (under the image)."""
        with dpg.plot(tag="rates_plot", height=-1, width=-1, no_title=True):
            dpg.add_plot_legend(location=dpg.mvPlot_Location_NorthEast)
            dpg.add_plot_axis(dpg.mvXAxis, label="time [s]", tag="rates_x")
            dpg.add_plot_axis(dpg.mvYAxis, label="emission rate [kg/h]", tag="rates_y")

    def refresh(self) -> None:
        build_results_panel(self.app, "results_group")
        build_rates_plot(self.app, "rates_y")

    def _build_exports(self) -> None:
        s = self.app.safe
        dpg.add_text("Export")
        with dpg.group(horizontal=True):
            dpg.add_input_text(
                label="folder",
                tag="export_dir",
                width=270,
                default_value=self.vm.store.last_dir or os.getcwd(),
            )
            dpg.add_button(label="...", callback=s(lambda *a: dpg.show_item("export_dialog")))
        dpg.add_input_text(
            label="file name start", tag="export_stem", width=160, default_value="qogi"
        )
        with dpg.group(horizontal=True):
            for label, kind in (
                ("CSV", "csv"),
                ("JSON", "json"),
                ("Plots PNG", "plots"),
                ("Frame PNG", "frame"),
                ("Report", "report"),
                ("Report PDF", "report_pdf"),
            ):
                dpg.add_button(
                    label=label, callback=s(lambda sd, a, u: self.on_export(u)), user_data=kind
                )
        with dpg.group(horizontal=True):
            dpg.add_button(label="Export all", callback=s(lambda *a: self.on_export("all")))
            dpg.add_button(
                label="Window screenshot", callback=s(lambda *a: self.on_export("window"))
            )

    def on_export(self, kind: str) -> bool:
        """Export ``kind`` (csv, json, plots, frame, report, report_pdf, all,
        window) into the folder and with the file name start of the form."""
        folder = Path(dpg.get_value("export_dir") or ".").expanduser()
        stem = (dpg.get_value("export_stem") or "qogi").strip()
        ex = self.vm.exporter
        if kind == "window":
            if not folder.is_dir():
                return self.vm.log.error(
                    f"could not save the screenshot: the folder {folder} does not exist"
                )
            return self.app.screenshot(folder / f"{stem}_window.png")
        target = {
            "csv": f"{stem}.csv",
            "json": f"{stem}.json",
            "plots": f"{stem}_rates.png",
            "frame": f"{stem}_frame.png",
            "report": f"{stem}_report.md",
            "report_pdf": f"{stem}_report.pdf",
        }
        fn = {
            "csv": ex.export_csv,
            "json": ex.export_json,
            "plots": ex.export_plots,
            "frame": ex.export_frame,
            "report": ex.export_report,
            "report_pdf": ex.export_report,
        }
        if kind == "all":
            return ex.export_all(folder, stem)
        return fn[kind](folder / target[kind])
