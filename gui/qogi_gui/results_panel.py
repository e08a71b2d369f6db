"""Dear PyGui widgets of the results: the side-by-side table, the comparison
chart, the pixel-status summary and the emission-rate time series.

Everything shown comes from :mod:`qogi_gui.results` (plain functions over a
``qogi.Result``); this module only lays it out.
"""

from __future__ import annotations

import math

import numpy as np

import dearpygui.dearpygui as dpg

from . import results
from .surfaces import SURFACE_COLOURS

__all__ = ["build_results_panel", "build_rates_plot"]

GREY = (150, 150, 150)
YELLOW = (255, 210, 90)


def _fmt(x, nd=4):
    return "n/a" if x is None or not math.isfinite(x) else f"{x:.{nd}g}"


def _colour_of(app, name):
    for s in app.vm.result_surfaces:
        if s.name == name:
            return s.colour
    return SURFACE_COLOURS[0]


def build_results_panel(app, parent) -> None:
    vm = app.vm
    dpg.delete_item(parent, children_only=True)
    res = vm.result
    if res is None:
        dpg.add_text("No result yet: draw a surface, check the Analysis tab and run.",
                     parent=parent, color=GREY, wrap=420)
        return
    if vm.result_partial:
        dpg.add_text("Partial result: the run was cancelled; these numbers rest on the frames "
                     "finished before that.", parent=parent, color=YELLOW, wrap=420)
    rows = results.rate_rows(res)
    surfaces = list(dict.fromkeys(r.surface for r in rows))
    species = list(dict.fromkeys(r.species for r in rows))
    by = {(r.surface, r.species): r for r in rows}

    dpg.add_text("Emission rate per surface (side by side)", parent=parent)
    with dpg.table(parent=parent, header_row=True, borders_innerV=True, borders_outerH=True,
                   policy=dpg.mvTable_SizingStretchProp, row_background=True):
        dpg.add_table_column(label="", init_width_or_weight=1.3)
        for s in surfaces:
            dpg.add_table_column(label=s, init_width_or_weight=1.0)
        for sp in species:
            lines = [
                (f"{sp} mean [kg/h]", lambda r: _fmt(r.mean_kg_h)),
                ("90% low [kg/h]", lambda r: _fmt(r.ci90_kg_h[0])),
                ("90% high [kg/h]", lambda r: _fmt(r.ci90_kg_h[1])),
                ("[g/h]", lambda r: _fmt(r.mean_g_h)),
                ("[SLPM]", lambda r: _fmt(r.mean_slpm)),
                ("truth [kg/h]", lambda r: _fmt(r.truth_kg_h) if r.truth_kg_h is not None
                 else "-"),
                ("error vs truth", lambda r: f"{r.error_pct:+.1f} %" if r.error_pct is not None
                 else "-"),
                ("frames (valid)", lambda r: f"{r.n_frames} ({r.n_frames_valid})"),
                ("pixels (median)", lambda r: _fmt(r.pixels_median, 4)),
                ("dominant uncertainty", lambda r: r.dominant_uncertainty or "-"),
                ("detection limit [kg/h]", lambda r: r.detection_text),
            ]
            for label, fn in lines:
                with dpg.table_row():
                    dpg.add_text(label, color=GREY)
                    for s in surfaces:
                        r = by.get((s, sp))
                        dpg.add_text(fn(r) if r is not None else "-",
                                     color=(255, 255, 255) if label.endswith("[kg/h]") and
                                     "mean" in label else (220, 220, 220))
    if vm.result_stale:
        dpg.add_text("Surfaces or settings changed since this run: run again to update.",
                     parent=parent, color=YELLOW, wrap=420)
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
                lo.append(max(0.0, r.mean_kg_h - r.ci90_kg_h[0]) if math.isfinite(
                    r.ci90_kg_h[0]) else 0.0)
                hi.append(max(0.0, r.ci90_kg_h[1] - r.mean_kg_h) if math.isfinite(
                    r.ci90_kg_h[1]) else 0.0)
            if xs:
                dpg.add_bar_series(xs, ys, weight=width * 0.9, label=sp, parent=ya)
                dpg.add_error_series(xs, ys, lo, hi, parent=ya)
            truth = next((by[(s, sp)].truth_kg_h for s in surfaces
                          if (s, sp) in by and by[(s, sp)].truth_kg_h is not None), None)
            if truth is not None:  # a line across the bars (fitting the axis takes it in)
                t = dpg.add_line_series([-0.6, len(surfaces) - 0.4], [truth, truth],
                                        label=f"truth {sp}", parent=ya)
                dpg.bind_item_theme(t, app._themes["truth"])
        dpg.set_axis_limits(xa, -0.6, len(surfaces) - 0.4)
        dpg.fit_axis_data(ya)

    status = results.pixel_status_rows(res)
    if status:
        dpg.add_text("Pixels (all quantified frames)", parent=parent)
        with dpg.table(parent=parent, header_row=True, policy=dpg.mvTable_SizingStretchProp,
                       borders_innerH=True):
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
    vm = app.vm
    dpg.delete_item(axis, children_only=True)
    res = vm.result
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
        dpg.bind_item_theme(line, app._themes[("thin", colour)])
        lo, hi = ser["ci90_kg_h"]
        t0, t1 = float(t[0]), float(t[-1])
        if math.isfinite(lo) and math.isfinite(hi):
            band = dpg.add_shade_series([t0, t1], [lo, lo], y2=[hi, hi],
                                        label=f"{label} 90% band", parent=axis)
            dpg.bind_item_theme(band, app._themes[("line", colour)])
        m = ser["mean_kg_h"]
        if math.isfinite(m):
            mean = dpg.add_line_series([t0, t1], [m, m], label=f"{label} mean {m:.3g} kg/h",
                                       parent=axis)
            dpg.bind_item_theme(mean, app._themes[("selected", colour)])
        if ser["truth_kg_h"] is not None:
            truths[ser["species"]] = ser["truth_kg_h"]
    for sp, v in truths.items():  # a line over the run (fitting the axis takes it in)
        t = dpg.add_line_series(span, [v, v], label=f"truth {sp} {v:.3g} kg/h", parent=axis)
        dpg.bind_item_theme(t, app._themes["truth"])
    dpg.fit_axis_data("rates_x")
    dpg.fit_axis_data(axis)
