"""Colours, plot themes and colour maps of the window."""

from __future__ import annotations

import dearpygui.dearpygui as dpg
import numpy as np

from .. import display
from ..surfaces import SURFACE_COLOURS

__all__ = ["LEFT_WIDTH", "GREY", "RED", "YELLOW", "GREEN", "rgb", "build_themes", "build_colormaps"]

LEFT_WIDTH = 440
GREY = (150, 150, 150)
RED = (255, 110, 100)
YELLOW = (255, 210, 90)
GREEN = (140, 230, 140)


def rgb(c, a=255):
    return (int(c[0]), int(c[1]), int(c[2]), a)


def build_themes() -> dict:
    """Themes by key: ("line" | "thin" | "marker" | "selected", surface colour),
    "region", "drawing", "vectors", "truth", "image_plot", "run", "cancel"."""
    themes = {}

    def line_theme(colour, weight, marker=False):
        with dpg.theme() as t:
            with dpg.theme_component(dpg.mvAll):
                dpg.add_theme_color(dpg.mvPlotCol_Line, rgb(colour), category=dpg.mvThemeCat_Plots)
                dpg.add_theme_color(
                    dpg.mvPlotCol_MarkerFill, rgb(colour), category=dpg.mvThemeCat_Plots
                )
                dpg.add_theme_color(
                    dpg.mvPlotCol_MarkerOutline, rgb(colour), category=dpg.mvThemeCat_Plots
                )
                dpg.add_theme_color(
                    dpg.mvPlotCol_Fill, rgb(colour, 60), category=dpg.mvThemeCat_Plots
                )
                dpg.add_theme_style(
                    dpg.mvPlotStyleVar_LineWeight, weight, category=dpg.mvThemeCat_Plots
                )
                if marker:
                    dpg.add_theme_style(
                        dpg.mvPlotStyleVar_Marker,
                        dpg.mvPlotMarker_Circle,
                        category=dpg.mvThemeCat_Plots,
                    )
                    dpg.add_theme_style(
                        dpg.mvPlotStyleVar_MarkerSize, 4.5, category=dpg.mvThemeCat_Plots
                    )
        return t

    for c in SURFACE_COLOURS:
        themes[("line", c)] = line_theme(c, 2.5)
        themes[("thin", c)] = line_theme(c, 1.5)
        themes[("marker", c)] = line_theme(c, 1.0, marker=True)
        themes[("selected", c)] = line_theme(c, 4.5)
    themes["region"] = line_theme((255, 255, 255), 1.5)
    themes["drawing"] = line_theme((255, 255, 255), 2.0, marker=True)
    themes["vectors"] = line_theme((255, 255, 255), 1.3)
    themes["truth"] = line_theme((230, 230, 230), 1.5)
    with dpg.theme() as t:
        with dpg.theme_component(dpg.mvAll):
            dpg.add_theme_style(dpg.mvPlotStyleVar_PlotPadding, 2, 2, category=dpg.mvThemeCat_Plots)
    themes["image_plot"] = t
    with dpg.theme() as t:
        with dpg.theme_component(dpg.mvButton):
            dpg.add_theme_color(dpg.mvThemeCol_Button, (40, 110, 60))
            dpg.add_theme_color(dpg.mvThemeCol_ButtonHovered, (50, 140, 75))
    themes["run"] = t
    with dpg.theme() as t:
        with dpg.theme_component(dpg.mvButton):
            dpg.add_theme_color(dpg.mvThemeCol_Button, (120, 45, 40))
            dpg.add_theme_color(dpg.mvThemeCol_ButtonHovered, (150, 60, 50))
    themes["cancel"] = t
    return themes


def build_colormaps() -> None:
    """Dear PyGui colour maps ``cmap_<name>`` of the display's colour maps."""
    with dpg.colormap_registry():
        for name in set(display.COLORMAPS) | set(display.OVERLAY_COLORMAPS):
            lut = display.colormap_lut(name)
            pts = lut[np.linspace(0, len(lut) - 1, 24).round().astype(int)]
            dpg.add_colormap(
                [[int(round(v * 255)) for v in c] for c in pts], False, tag=f"cmap_{name}"
            )
