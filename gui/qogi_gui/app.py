"""The Dear PyGui window of the viewer.

Widgets only: every user action is forwarded to :class:`~qogi_gui.viewmodel.ViewModel`
and the window redraws what the view-model holds (it watches ``vm.rev`` to
redraw only what changed). The render loop is ours (:meth:`App.frame`), with
Dear PyGui's callbacks run on this same thread, so the view-model is only
ever touched from one thread; long work runs in the view-model's background
jobs and the loop keeps drawing.

Every callback goes through :meth:`App._safe`: an unexpected exception
becomes a message in the window (and a traceback on the terminal), never a
crash.

The handlers named ``on_*`` and :meth:`App.image_click` are what the widgets
call; scripts and the smoke test call them too.
"""

from __future__ import annotations

import math
import os
import sys
import time
import traceback
from pathlib import Path
from typing import Optional

import numpy as np

import dearpygui.dearpygui as dpg

from . import display, results
from .settings import AVERAGING, BACKGROUNDS, FIELDS, GAS_TEMPERATURE_MODES, velocity_choices
from .surfaces import flow_arrow
from .viewmodel import MODES, SPEEDS, ViewModel

__all__ = ["App", "run", "check_display", "NoDisplayError"]

LEFT_WIDTH = 440
GREY = (150, 150, 150)
RED = (255, 110, 100)
YELLOW = (255, 210, 90)
GREEN = (140, 230, 140)
MODE_LABELS = {"view": "look (pan, zoom, read-out)", "line": "draw a line (2 clicks)",
               "polyline": "draw a polyline (right-click / Enter ends)",
               "region": "pick background region (2 corners)", "source": "pick the source",
               "edit": "edit (drag points)"}
QUANTITY_CHOICES = {"band radiance [W/(m2 sr)]": "radiance",
                    "radiometric temperature [K]": "radiometric_temperature"}
RANGE_CHOICES = {"auto (whole recording)": "recording", "auto (this frame)": "frame",
                 "fixed": "fixed"}


def _rgb(c, a=255):
    return (int(c[0]), int(c[1]), int(c[2]), a)


class App:
    """The viewer window around a :class:`ViewModel`.

    Parameters
    ----------
    vm : ViewModel, optional
    width, height : int, px
        Initial window size.
    """

    def __init__(self, vm: Optional[ViewModel] = None, width: int = 1440, height: int = 900,
                 vsync: bool = True):
        self.vm = vm if vm is not None else ViewModel()
        self.width, self.height = width, height
        self.vsync = vsync
        self._seen = {}
        self._tex_shape = None
        self._overlay_items = []
        self._result_items = []
        self._drag_points = []
        self._n_messages = 0
        self._popup_queue = []
        self._frames_drawn = 0
        self._video_frames = 0
        self._fps_t0 = time.monotonic()
        self.fps = 0.0
        self.video_fps = 0.0
        self._last_range = None
        self._last_shown = None
        self._themes = {}
        self._fit_rates = 0
        self._unlock_axes = 0
        self._readout_text = ""

    # ================================================================= safety
    def _safe(self, fn):
        """Wrap a callback so that any exception becomes a message in the window."""
        def cb(sender=None, app_data=None, user_data=None):
            try:
                return fn(sender, app_data, user_data)
            except Exception as e:  # the window must survive anything a handler does
                traceback.print_exc()
                self.vm.log.error(f"internal error in the viewer ({type(e).__name__}: {e}); "
                               "details were printed to the terminal")
        return cb

    # ================================================================= build
    def build(self) -> None:
        """Create the context, the widgets and the viewport (shown)."""
        dpg.create_context()
        dpg.configure_app(manual_callback_management=True)
        dpg.create_viewport(title="qogi viewer", width=self.width, height=self.height,
                            min_width=900, min_height=600, vsync=self.vsync)
        self._build_themes()
        self._build_colormaps()
        dpg.add_texture_registry(tag="textures")
        with dpg.window(tag="main", no_scrollbar=True):
            self._build_menu()
            with dpg.group(horizontal=True):
                with dpg.child_window(width=LEFT_WIDTH, tag="left", border=False):
                    self._build_tabs()
                with dpg.child_window(width=-1, tag="right", border=False, no_scrollbar=True):
                    self._build_image_area()
            self._build_status_bar()
        self._build_dialogs()
        self._build_handlers()
        self._refresh_recent()
        dpg.set_viewport_resize_callback(self._safe(lambda *a: self._layout()))
        dpg.setup_dearpygui()
        dpg.show_viewport()
        dpg.set_primary_window("main", True)
        self._layout()

    def _build_themes(self) -> None:
        from .surfaces import SURFACE_COLOURS

        def line_theme(colour, weight, marker=False):
            with dpg.theme() as t:
                with dpg.theme_component(dpg.mvAll):
                    dpg.add_theme_color(dpg.mvPlotCol_Line, _rgb(colour), category=dpg.mvThemeCat_Plots)
                    dpg.add_theme_color(dpg.mvPlotCol_MarkerFill, _rgb(colour),
                                        category=dpg.mvThemeCat_Plots)
                    dpg.add_theme_color(dpg.mvPlotCol_MarkerOutline, _rgb(colour),
                                        category=dpg.mvThemeCat_Plots)
                    dpg.add_theme_color(dpg.mvPlotCol_Fill, _rgb(colour, 60),
                                        category=dpg.mvThemeCat_Plots)
                    dpg.add_theme_style(dpg.mvPlotStyleVar_LineWeight, weight,
                                        category=dpg.mvThemeCat_Plots)
                    if marker:
                        dpg.add_theme_style(dpg.mvPlotStyleVar_Marker, dpg.mvPlotMarker_Circle,
                                            category=dpg.mvThemeCat_Plots)
                        dpg.add_theme_style(dpg.mvPlotStyleVar_MarkerSize, 4.5,
                                            category=dpg.mvThemeCat_Plots)
            return t

        for c in SURFACE_COLOURS:
            self._themes[("line", c)] = line_theme(c, 2.5)
            self._themes[("thin", c)] = line_theme(c, 1.5)
            self._themes[("marker", c)] = line_theme(c, 1.0, marker=True)
            self._themes[("selected", c)] = line_theme(c, 4.5)
        self._themes["region"] = line_theme((255, 255, 255), 1.5)
        self._themes["drawing"] = line_theme((255, 255, 255), 2.0, marker=True)
        self._themes["vectors"] = line_theme((255, 255, 255), 1.3)
        self._themes["truth"] = line_theme((230, 230, 230), 1.5)
        with dpg.theme() as t:
            with dpg.theme_component(dpg.mvAll):
                dpg.add_theme_style(dpg.mvPlotStyleVar_PlotPadding, 2, 2,
                                    category=dpg.mvThemeCat_Plots)
        self._themes["image_plot"] = t
        with dpg.theme() as t:
            with dpg.theme_component(dpg.mvButton):
                dpg.add_theme_color(dpg.mvThemeCol_Button, (40, 110, 60))
                dpg.add_theme_color(dpg.mvThemeCol_ButtonHovered, (50, 140, 75))
        self._themes["run"] = t
        with dpg.theme() as t:
            with dpg.theme_component(dpg.mvButton):
                dpg.add_theme_color(dpg.mvThemeCol_Button, (120, 45, 40))
                dpg.add_theme_color(dpg.mvThemeCol_ButtonHovered, (150, 60, 50))
        self._themes["cancel"] = t

    def _build_colormaps(self) -> None:
        with dpg.colormap_registry():
            for name in set(display.COLORMAPS) | set(display.OVERLAY_COLORMAPS):
                lut = display.colormap_lut(name)
                pts = lut[np.linspace(0, len(lut) - 1, 24).round().astype(int)]
                dpg.add_colormap([[int(round(v * 255)) for v in c] for c in pts], False,
                                 tag=f"cmap_{name}")

    def _build_menu(self) -> None:
        s = self._safe
        with dpg.menu_bar():
            with dpg.menu(label="File"):
                dpg.add_menu_item(label="Open recording...", callback=s(self.on_open_dialog))
                dpg.add_menu_item(label="Load the demo scene", callback=s(self.on_demo))
                dpg.add_menu(label="Recent", tag="recent_menu")
                dpg.add_separator()
                dpg.add_menu_item(label="Export all results...", callback=s(
                    lambda *a: self.on_export("all")))
                dpg.add_menu_item(label="Save window screenshot",
                                  callback=s(lambda *a: self.on_export("window")))
                dpg.add_separator()
                dpg.add_menu_item(label="Quit", callback=s(lambda *a: dpg.stop_dearpygui()))
            with dpg.menu(label="View"):
                dpg.add_menu_item(label="Fit image", callback=s(lambda *a: self.fit_image()))
            with dpg.menu(label="Help"):
                dpg.add_menu_item(label="Mouse and keys", callback=s(
                    lambda *a: self._popup("Mouse and keys", HELP_TEXT, "info")))

    # ----------------------------------------------------------------- left tabs
    def _build_tabs(self) -> None:
        s = self._safe
        with dpg.tab_bar(tag="tabs"):
            with dpg.tab(label="Recording", tag="tab_recording"):
                with dpg.group(horizontal=True):
                    dpg.add_button(label="Open recording...", callback=s(self.on_open_dialog))
                    dpg.add_button(label="Load demo scene", tag="demo_button",
                                   callback=s(self.on_demo))
                dpg.add_spacer(height=4)
                with dpg.table(tag="meta_table", header_row=False, borders_innerH=True,
                               policy=dpg.mvTable_SizingStretchProp):
                    dpg.add_table_column(init_width_or_weight=0.36)
                    dpg.add_table_column(init_width_or_weight=0.64)
                dpg.add_text("Open a recording (.h5) or load the demo scene.", tag="meta_hint",
                             wrap=LEFT_WIDTH - 20, color=GREY)
                dpg.add_spacer(height=8)
                dpg.add_text("Recent recordings")
                dpg.add_group(tag="recent_list")
            with dpg.tab(label="Display", tag="tab_display"):
                self._build_display_tab()
            with dpg.tab(label="Surfaces", tag="tab_surfaces"):
                self._build_surfaces_tab()
            with dpg.tab(label="Analysis", tag="tab_analysis"):
                self._build_analysis_tab()
            with dpg.tab(label="Results", tag="tab_results"):
                dpg.add_group(tag="results_group")
                dpg.add_separator()
                self._build_export_section()

    def _build_display_tab(self) -> None:
        s = self._safe
        dpg.add_combo([], label="channel", tag="d_channel", width=260,
                      callback=s(self._on_channel))
        dpg.add_radio_button(list(QUANTITY_CHOICES), tag="d_quantity",
                             callback=s(lambda sd, a, u: self.vm.set_display(
                                 quantity=QUANTITY_CHOICES[a])))
        dpg.add_combo(list(display.COLORMAPS), label="colour map", tag="d_cmap", width=160,
                      default_value=display.COLORMAPS[0],
                      callback=s(lambda sd, a, u: self.vm.set_display(colormap=a)))
        dpg.add_radio_button(list(RANGE_CHOICES), tag="d_range", horizontal=False,
                             callback=s(lambda sd, a, u: self.vm.set_display(
                                 range_mode=RANGE_CHOICES[a])))
        with dpg.group(horizontal=True):
            dpg.add_input_double(label="min", tag="d_min", width=120, format="%.6g",
                                 on_enter=True, callback=s(self._on_fixed_range))
            dpg.add_input_double(label="max", tag="d_max", width=120, format="%.6g",
                                 on_enter=True, callback=s(self._on_fixed_range))
        dpg.add_button(label="Fix the range shown now", tag="d_fix_now",
                       callback=s(self._on_fix_now))
        dpg.add_text("Zoom with the mouse wheel, pan by dragging (in look mode), "
                     "double-click to fit.", wrap=LEFT_WIDTH - 20, color=GREY)
        dpg.add_separator()
        dpg.add_text("Results on the video")
        dpg.add_checkbox(label="column density overlay", tag="d_overlay", default_value=True,
                         callback=s(lambda sd, a, u: self.vm.set_display(show_overlay=a)))
        dpg.add_combo([], label="species", tag="d_overlay_species", width=120,
                      callback=s(lambda sd, a, u: self.vm.set_display(overlay_species=a)))
        dpg.add_combo(list(display.OVERLAY_COLORMAPS), label="overlay colours", width=120,
                      default_value=display.OVERLAY_COLORMAPS[0], tag="d_overlay_cmap",
                      callback=s(lambda sd, a, u: self.vm.set_display(overlay_colormap=a)))
        dpg.add_checkbox(label="velocity vectors", tag="d_vectors", default_value=True,
                         callback=s(lambda sd, a, u: self.vm.set_display(show_vectors=a)))
        with dpg.group(horizontal=True):
            dpg.add_button(label="< frame with maps", tag="d_prev_maps",
                           callback=s(lambda *a: self.vm.seek_map_frame(-1)))
            dpg.add_button(label="frame with maps >", tag="d_next_maps",
                           callback=s(lambda *a: self.vm.seek_map_frame(1)))
        dpg.add_text("", tag="d_overlay_note", wrap=LEFT_WIDTH - 20, color=GREY)

    def _build_surfaces_tab(self) -> None:
        s = self._safe
        dpg.add_text("What a click on the image does:")
        dpg.add_radio_button([MODE_LABELS[m] for m in MODES], tag="mode",
                             default_value=MODE_LABELS["view"],
                             callback=s(lambda sd, a, u: self.vm.set_mode(
                                 {v: k for k, v in MODE_LABELS.items()}[a])))
        with dpg.group(horizontal=True):
            dpg.add_button(label="Finish surface", callback=s(lambda *a: self.vm.finish_drawing()))
            dpg.add_button(label="Undo point", callback=s(lambda *a: self.vm.undo_point()))
            dpg.add_button(label="Cancel drawing", callback=s(lambda *a: self.vm.cancel_drawing()))
        with dpg.group(horizontal=True):
            dpg.add_button(label="Automatic surfaces at", tag="auto_surfaces_button",
                           callback=s(lambda *a: self.on_auto_surfaces()))
            dpg.add_input_text(tag="auto_distances", default_value="30, 60, 90", width=110)
            dpg.add_text("px from the source")
        dpg.add_text("Flux counts positive in the direction of each surface's arrow: the "
                     "left-hand side walking from its first point to its last. Reverse a "
                     "surface to flip it, or set the source (Analysis) to orient them all "
                     "away from it.", wrap=LEFT_WIDTH - 20, color=GREY)
        dpg.add_separator()
        dpg.add_text("Control surfaces")
        dpg.add_group(tag="surface_list")
        dpg.add_separator()
        dpg.add_text("Background region: none", tag="region_text")
        with dpg.group(horizontal=True):
            dpg.add_button(label="Pick region", callback=s(lambda *a: self.set_mode("region")))
            dpg.add_button(label="Clear region", callback=s(lambda *a: self.vm.set_region(None)))

    def on_auto_surfaces(self) -> None:
        text = dpg.get_value("auto_distances") or ""
        try:
            dists = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
        except ValueError:
            self.vm.log.error(f"distances: give numbers of pixels separated by commas; got {text!r}")
            return
        self.vm.auto_surfaces(dists)

    def _build_analysis_tab(self) -> None:
        s = self._safe
        w = 130
        msgw = LEFT_WIDTH - 20

        def hint(key):
            dpg.add_text("", tag=f"msg_{key}", wrap=msgw, color=GREY, indent=12)

        def text_field(key, label, unit=""):
            with dpg.group(horizontal=True, tag=f"row_{key}"):
                dpg.add_input_text(label=f"{label}{' [' + unit + ']' if unit else ''}",
                                   tag=f"f_{key}", width=w,
                                   callback=s(lambda sd, a, u: self._on_field(u, a)),
                                   user_data=key)
            hint(key)

        dpg.add_text("Species")
        dpg.add_group(tag="species_group", horizontal=True)
        hint("species")
        dpg.add_combo(list(GAS_TEMPERATURE_MODES), label="gas temperature", tag="f_gas_mode",
                      width=w, default_value="ambient",
                      callback=s(lambda sd, a, u: self._on_field("gas_temperature_mode", a)))
        text_field("gas_temperature_K", "given gas temperature", "K")
        dpg.add_combo(velocity_choices(), label="velocity source", tag="f_velocity", width=w,
                      default_value=velocity_choices()[0],
                      callback=s(lambda sd, a, u: self._on_field("velocity", a)))
        hint("velocity")
        text_field("wind_speed_m_s", "wind speed", "m/s")
        text_field("exit_velocity_m_s", "exit velocity", "m/s")
        dpg.add_combo(list(AVERAGING), label="averaging order", tag="f_averaging", width=w,
                      default_value=AVERAGING[0],
                      callback=s(lambda sd, a, u: self._on_field("averaging", a)))
        hint("averaging")
        dpg.add_combo(list(BACKGROUNDS), label="background", tag="f_background", width=w,
                      default_value=BACKGROUNDS[0],
                      callback=s(lambda sd, a, u: self._on_field("background", a)))
        hint("background")
        text_field("background_percentile", "background percentile", "%")
        dpg.add_separator()
        dpg.add_text("Scene (empty: the recording's value)")
        text_field("distance_m", "distance", "m")
        text_field("ambient_temperature_K", "ambient temperature", "K")
        text_field("pressure_Pa", "pressure", "Pa")
        text_field("sigma_m", "plume depth sigma", "m")
        dpg.add_separator()
        text_field("frame_start", "first frame")
        text_field("frame_stop", "stop frame")
        with dpg.group(horizontal=True):
            dpg.add_checkbox(label="source at", tag="f_use_source",
                             callback=s(lambda sd, a, u: self._on_field("use_source", a)))
            dpg.add_input_text(tag="f_source_x", width=60, hint="x",
                               callback=s(lambda sd, a, u: self._on_field("source_x", a)))
            dpg.add_input_text(tag="f_source_y", width=60, hint="y",
                               callback=s(lambda sd, a, u: self._on_field("source_y", a)))
            dpg.add_button(label="pick", callback=s(lambda *a: self.set_mode("source")))
        hint("source")
        text_field("num_threads", "threads")
        dpg.add_checkbox(label="keep per-pixel maps (overlay, vectors)", tag="f_keep_maps",
                         default_value=True,
                         callback=s(lambda sd, a, u: self._on_field("keep_maps", a)))
        dpg.add_spacer(height=6)
        with dpg.group(horizontal=True):
            dpg.add_button(label="Run quantification", tag="run_button", width=180, height=30,
                           callback=s(self.on_run))
            dpg.bind_item_theme("run_button", self._themes["run"])

    def _build_export_section(self) -> None:
        s = self._safe
        dpg.add_text("Export")
        with dpg.group(horizontal=True):
            dpg.add_input_text(label="folder", tag="export_dir", width=270,
                               default_value=self.vm.store.last_dir or os.getcwd())
            dpg.add_button(label="...", callback=s(lambda *a: dpg.show_item("export_dialog")))
        dpg.add_input_text(label="file name start", tag="export_stem", width=160,
                           default_value="qogi")
        with dpg.group(horizontal=True):
            for label, kind in (("CSV", "csv"), ("JSON", "json"), ("Plots PNG", "plots"),
                                ("Frame PNG", "frame"), ("Report", "report"),
                                ("Report PDF", "report_pdf")):
                dpg.add_button(label=label, callback=s(lambda sd, a, u: self.on_export(u)),
                               user_data=kind)
        with dpg.group(horizontal=True):
            dpg.add_button(label="Export all", callback=s(lambda *a: self.on_export("all")))
            dpg.add_button(label="Window screenshot",
                           callback=s(lambda *a: self.on_export("window")))

    # ----------------------------------------------------------------- right side
    def _build_image_area(self) -> None:
        s = self._safe
        with dpg.group(horizontal=True):
            with dpg.plot(tag="img_plot", height=480, width=-90, equal_aspects=True,
                          no_menus=True, no_box_select=True, no_mouse_pos=True,
                          no_title=True):
                dpg.add_plot_axis(dpg.mvXAxis, tag="img_x", no_gridlines=True)
                dpg.add_plot_axis(dpg.mvYAxis, tag="img_y", invert=True, no_gridlines=True)
                dpg.add_line_series([], [], segments=True, tag="vectors", parent="img_y")
                dpg.bind_item_theme("vectors", self._themes["vectors"])
            dpg.bind_item_theme("img_plot", self._themes["image_plot"])
            dpg.add_colormap_scale(tag="img_scale", width=85, height=480, min_scale=0,
                                   max_scale=1, colormap="cmap_inferno", format="%.4g")
        with dpg.group(horizontal=True):
            dpg.add_button(label="|<", callback=s(lambda *a: self.vm.step(-self.vm.frame)))
            dpg.add_button(label="<", callback=s(lambda *a: self.vm.step(-1)))
            dpg.add_button(label="Play", tag="play_button", width=60, callback=s(self.on_play))
            dpg.add_button(label=">", callback=s(lambda *a: self.vm.step(1)))
            dpg.add_slider_int(tag="frame_slider", width=-330, min_value=0, max_value=0,
                               callback=s(lambda sd, a, u: self.vm.seek(a)))
            dpg.add_combo([f"{v:g}x" for v in SPEEDS], tag="speed", width=70,
                          default_value="1x",
                          callback=s(lambda sd, a, u: self.vm.set_speed(a.rstrip("x"))))
            dpg.add_text("", tag="time_text")
        dpg.add_text("", tag="readout", color=(200, 220, 255))
        with dpg.plot(tag="rates_plot", height=-1, width=-1, no_title=True):
            dpg.add_plot_legend(location=dpg.mvPlot_Location_NorthEast)
            dpg.add_plot_axis(dpg.mvXAxis, label="time [s]", tag="rates_x")
            dpg.add_plot_axis(dpg.mvYAxis, label="emission rate [kg/h]", tag="rates_y")

    def _build_status_bar(self) -> None:
        s = self._safe
        dpg.add_separator()
        with dpg.group(horizontal=True, tag="status_bar"):
            dpg.add_progress_bar(tag="progress", width=420, overlay="idle")
            dpg.add_button(label="Cancel", tag="cancel_button", callback=s(self.on_cancel))
            dpg.bind_item_theme("cancel_button", self._themes["cancel"])
            dpg.add_button(label="Messages", callback=s(lambda *a: self.show_messages()))
            dpg.add_text("", tag="status_text")
            dpg.add_text("", tag="fps_text", color=GREY)

    def _build_dialogs(self) -> None:
        s = self._safe
        with dpg.file_dialog(tag="open_dialog", show=False, width=760, height=460, modal=True,
                             callback=s(self._on_open_chosen),
                             default_path=self.vm.store.last_dir or os.getcwd()):
            dpg.add_file_extension("Recordings and camera files{.h5,.hdf5,.seq,.csq,.jpg,.fff,.hcc}",
                                   color=(150, 255, 150, 255))
            dpg.add_file_extension("Recordings (*.h5 *.hdf5){.h5,.hdf5}", color=(150, 255, 150, 255))
            dpg.add_file_extension("FLIR (*.seq *.csq *.jpg *.fff){.seq,.csq,.jpg,.fff}",
                                   color=(150, 200, 255, 255))
            dpg.add_file_extension("Telops (*.hcc){.hcc}", color=(150, 200, 255, 255))
            dpg.add_file_extension(".*")
        self._build_scene_form()
        dpg.add_file_dialog(tag="export_dialog", show=False, width=760, height=460, modal=True,
                            directory_selector=True,
                            callback=s(lambda sd, a, u: dpg.set_value(
                                "export_dir", a.get("file_path_name", ""))))
        with dpg.window(tag="popup", show=False, modal=True, no_collapse=True, width=560,
                        label="qogi", pos=(300, 200)):
            dpg.add_text("", tag="popup_text", wrap=530)
            dpg.add_button(label="OK", width=80, callback=lambda: dpg.hide_item("popup"))

    def _build_scene_form(self) -> None:
        """The small form that asks for a camera file's missing scene facts."""
        from qogi.presets import camera_preset_names

        from .scene_form import FIELDS
        s = self._safe
        with dpg.window(tag="scene_form", show=False, modal=True, no_collapse=True, width=620,
                        label="Scene facts", pos=(260, 180),
                        on_close=s(lambda *a: self.vm.cancel_scene())):
            dpg.add_text("", tag="scene_title", wrap=590)
            for key, (label, unit) in FIELDS.items():
                with dpg.group(horizontal=True):
                    dpg.add_text(f"{label} [{unit}]" if key != "camera" else label)
                    if key == "camera":
                        dpg.add_combo(list(camera_preset_names()), tag="scene_camera_preset",
                                      width=120, callback=lambda sd, a, u: dpg.set_value(
                                          "scene_f_camera", a))
                    dpg.add_input_text(tag=f"scene_f_{key}", width=220)
                dpg.add_text("", tag=f"scene_hint_{key}", color=(170, 170, 170, 255), wrap=590)
            dpg.add_text("", tag="scene_error", color=(255, 120, 120, 255), wrap=590)
            with dpg.group(horizontal=True):
                dpg.add_button(label="Open", width=90, callback=s(self.on_scene_submit))
                dpg.add_button(label="Cancel", width=90,
                               callback=s(lambda *a: self.vm.cancel_scene()))

    def on_scene_submit(self, *args) -> bool:
        from .scene_form import FIELDS
        return self.vm.submit_scene({k: dpg.get_value(f"scene_f_{k}") for k in FIELDS})

    def _refresh_scene_form(self) -> None:
        from .scene_form import FIELDS
        req = self.vm.scene_request
        if req is None:
            dpg.hide_item("scene_form")
            return
        dpg.set_value("scene_title", req.title)
        for key in FIELDS:
            dpg.set_value(f"scene_f_{key}", req.values.get(key, ""))
            err = req.errors.get(key, "")
            dpg.set_value(f"scene_hint_{key}", err or req.hint(key))
        dpg.set_value("scene_error", req.error)
        dpg.show_item("scene_form")

    def _build_handlers(self) -> None:
        s = self._safe
        with dpg.handler_registry():
            dpg.add_mouse_click_handler(button=dpg.mvMouseButton_Left,
                                        callback=s(lambda *a: self._mouse_click("left")))
            dpg.add_mouse_click_handler(button=dpg.mvMouseButton_Right,
                                        callback=s(lambda *a: self._mouse_click("right")))
            dpg.add_key_press_handler(callback=s(self._on_key))

    def _layout(self) -> None:
        h = dpg.get_viewport_client_height()
        img_h = max(240, int(0.56 * (h - 90)))
        dpg.configure_item("img_plot", height=img_h)
        dpg.configure_item("img_scale", height=img_h)
        dpg.configure_item("left", height=h - 80)
        dpg.configure_item("right", height=h - 80)

    # ================================================================= the loop
    def frame(self) -> None:
        """One iteration: callbacks, view-model updates, redraw what changed, render."""
        dpg.run_callbacks(dpg.get_callback_queue())
        try:
            self.update()
        except Exception as e:  # keep the window alive whatever a redraw hits
            traceback.print_exc()
            self.vm.log.error(f"internal error while drawing ({type(e).__name__}: {e})")
        dpg.render_dearpygui_frame()
        self._frames_drawn += 1

    def loop(self) -> None:
        while dpg.is_dearpygui_running():
            self.frame()

    def close(self) -> None:
        self.vm.close()
        dpg.destroy_context()

    def _changed(self, key: str) -> bool:
        v = self.vm.rev[key]
        if self._seen.get(key) != v:
            self._seen[key] = v
            return True
        return False

    def update(self) -> None:
        vm = self.vm
        vm.poll()
        new_frame = vm.tick()
        if self._changed("recording"):
            self._refresh_recording()
        if self._changed("settings"):
            self._refresh_settings()
        if self._changed("scene_request"):
            self._refresh_scene_form()
        result_changed = self._changed("result")
        if result_changed:
            self._refresh_results()
        display_changed = self._changed("display")
        if vm.recording is not None:
            shown = (vm.frame, vm.rev["display"], vm.rev["result"], vm.rev["recording"])
            if shown != self._last_shown:
                self._last_shown = shown
                self._upload_frame()
                self._video_frames += 1
            if display_changed:
                self._refresh_display_widgets()
        if self._changed("surfaces") or result_changed:
            self._refresh_overlays()
        if self._fit_rates:
            self._fit_rates -= 1
            dpg.fit_axis_data("rates_x")
            dpg.fit_axis_data("rates_y")
        self._refresh_playback()
        self._refresh_progress()
        self._refresh_messages()
        self._refresh_readout()
        now = time.monotonic()
        if now - self._fps_t0 >= 1.0:
            dt = now - self._fps_t0
            self.fps = self._frames_drawn / dt
            self.video_fps = self._video_frames / dt
            self._frames_drawn = self._video_frames = 0
            self._fps_t0 = now
            dpg.set_value("fps_text", f"playing: {self.fps:.0f} frames drawn/s, "
                                      f"{self.video_fps:.0f} recording frames shown/s"
                          if self.vm.playing else "")

    # ================================================================= refreshers
    def _refresh_recording(self) -> None:
        vm = self.vm
        dpg.delete_item("meta_table", children_only=True, slot=1)
        for label, value in vm.metadata_rows():
            with dpg.table_row(parent="meta_table"):
                dpg.add_text(label, color=GREY)
                dpg.add_text(value, wrap=260)
        dpg.configure_item("meta_hint", show=vm.recording is None)
        self._refresh_recent()
        rec = vm.recording
        if rec is None:
            return
        dpg.set_viewport_title(f"qogi viewer - {os.path.basename(vm.recording_path or '')}")
        dpg.configure_item("frame_slider", max_value=max(0, rec.n_frames - 1))
        dpg.configure_item("d_channel", items=[f"{k}: {ch.name}" for k, ch in
                                               enumerate(rec.channels)])
        dpg.set_value("d_channel", f"0: {rec.channels[0].name}")
        shape = (rec.height, rec.width)
        if self._tex_shape != shape:
            for tag in ("frame_series", "overlay_series", "frame_tex", "overlay_tex"):
                if dpg.does_item_exist(tag):
                    dpg.delete_item(tag)
            dpg.add_raw_texture(rec.width, rec.height, np.zeros(rec.width * rec.height * 4,
                                                                np.float32),
                                format=dpg.mvFormat_Float_rgba, tag="frame_tex",
                                parent="textures")
            dpg.add_raw_texture(rec.width, rec.height, np.zeros(rec.width * rec.height * 4,
                                                                np.float32),
                                format=dpg.mvFormat_Float_rgba, tag="overlay_tex",
                                parent="textures")
            # Texture row 0 is the image's top row; the y axis runs down (inverted),
            # so flip v to keep pixel (x, y) at plot (x, y).
            kw = dict(uv_min=(0.0, 1.0), uv_max=(1.0, 0.0), parent="img_y")
            dpg.add_image_series("frame_tex", (-0.5, -0.5), (rec.width - 0.5, rec.height - 0.5),
                                 tag="frame_series", before="vectors", **kw)
            dpg.add_image_series("overlay_tex", (-0.5, -0.5),
                                 (rec.width - 0.5, rec.height - 0.5), tag="overlay_series",
                                 before="vectors", **kw)
            self._tex_shape = shape
        self._last_shown = None
        self._refresh_display_widgets()
        self.fit_image()

    def fit_image(self) -> None:
        rec = self.vm.recording
        if rec is None:
            return
        dpg.set_axis_limits("img_x", -0.5, rec.width - 0.5)
        dpg.set_axis_limits("img_y", -0.5, rec.height - 0.5)
        self._unlock_axes = 2

    def _refresh_recent(self) -> None:
        dpg.delete_item("recent_menu", children_only=True)
        dpg.delete_item("recent_list", children_only=True)
        recent = self.vm.store.recent
        if not recent:
            dpg.add_menu_item(label="(none yet)", parent="recent_menu", enabled=False)
            dpg.add_text("(none yet)", parent="recent_list", color=GREY)
        open_it = self._safe(lambda sd, a, u: self.vm.open(u, background=True))
        for p in recent:
            dpg.add_menu_item(label=p, parent="recent_menu", user_data=p, callback=open_it)
            name = os.path.basename(p)
            dpg.add_button(label=name if len(name) < 52 else "..." + name[-49:],
                           parent="recent_list", user_data=p, callback=open_it)
            with dpg.tooltip(dpg.last_item()):
                dpg.add_text(p)

    def _refresh_display_widgets(self) -> None:
        d, rec = self.vm.display, self.vm.recording
        if rec is not None:
            dpg.set_value("d_channel", f"{d.channel}: {rec.channels[d.channel].name}")
        dpg.set_value("d_quantity", {v: k for k, v in QUANTITY_CHOICES.items()}[d.quantity])
        dpg.set_value("d_cmap", d.colormap)
        dpg.set_value("d_range", {v: k for k, v in RANGE_CHOICES.items()}[d.range_mode])
        dpg.set_value("d_min", d.fixed_min)
        dpg.set_value("d_max", d.fixed_max)
        dpg.set_value("d_overlay", d.show_overlay)
        dpg.set_value("d_vectors", d.show_vectors)
        dpg.configure_item("img_scale", colormap=f"cmap_{d.colormap}")

    def _upload_frame(self) -> None:
        vm = self.vm
        rgba = vm.render()
        dpg.set_value("frame_tex", rgba)
        over = vm.render_overlay()
        if over is not None:
            dpg.set_value("overlay_tex", over)
        dpg.configure_item("overlay_series", show=over is not None)
        tails, heads, scale = vm.vectors(spacing=max(8, vm.recording.width // 28))
        xs, ys = results.arrow_segments(tails, heads, min_head=1.5)
        dpg.set_value("vectors", [list(xs), list(ys)])
        note = ""
        if vm.result is not None and over is not None:
            sp = vm.overlay.species()
            note = (f"overlay: {sp} column density 0 .. {vm.overlay_vmax() * 1e3:.3g} g/m2")
            if scale > 0:
                note += (f"; vectors: 1 px/frame = {vm.px_per_frame_to_m_s():.3g} m/s, "
                         f"drawn {scale:.2g} px long")
        elif vm.result is not None and not vm.result_has_maps:
            note = "run with 'keep per-pixel maps' to see the overlay and vectors"
        if vm.result is not None and vm.result_has_maps:
            kept = vm.map_frames()
            if len(kept) < vm.n_frames:
                note += (("; " if note else "") + f"maps kept for {len(kept)} of {vm.n_frames} "
                         "frames: step between them with the buttons above")
        dpg.set_value("d_overlay_note", note)
        lo, hi = vm.last_range
        if (lo, hi) != self._last_range:
            self._last_range = (lo, hi)
            dpg.configure_item("img_scale", min_scale=lo, max_scale=hi)

    def _refresh_overlays(self) -> None:
        """Surfaces, their arrows and names, the region, the drawing in progress."""
        vm = self.vm
        for item in self._overlay_items + self._drag_points:
            if dpg.does_item_exist(item):
                dpg.delete_item(item)
        self._overlay_items, self._drag_points = [], []
        rec = vm.recording
        if rec is None:
            return
        arrow_len = max(6.0, 0.05 * max(rec.width, rec.height))

        def series(xs, ys, theme, segments=False, scatter=False):
            if scatter:
                t = dpg.add_scatter_series(list(xs), list(ys), parent="img_y")
            else:
                t = dpg.add_line_series(list(xs), list(ys), parent="img_y", segments=segments)
            dpg.bind_item_theme(t, self._themes[theme])
            self._overlay_items.append(t)
            return t

        for i, srf in enumerate(vm.surfaces):
            xs, ys = zip(*srf.points)
            c = srf.colour
            series(xs, ys, ("selected", c) if i == vm.selected else ("line", c))
            series(xs, ys, ("marker", c), scatter=True)
            arrow = flow_arrow(srf.points, arrow_len)
            if arrow is not None:
                ax, ay = results.arrow_segments(np.array([arrow[0]]), np.array([arrow[1]]))
                series(ax, ay, ("line", c), segments=True)
            x0, y0 = srf.points[0]
            self._overlay_items.append(dpg.add_plot_annotation(
                label=srf.name, default_value=(x0, y0), offset=(-12, -10), color=_rgb(c, 200),
                parent="img_plot"))
            if vm.mode == "edit":
                for j, (x, y) in enumerate(srf.points):
                    self._drag_points.append(dpg.add_drag_point(
                        default_value=(x, y), color=_rgb(c), parent="img_plot",
                        user_data=(i, j), show_label=False,
                        callback=self._safe(self._on_drag)))
        if vm.drawing is not None and vm.drawing.points:
            xs, ys = zip(*vm.drawing.points)
            series(xs, ys, "drawing")
        if vm.region is not None:
            r = vm.region
            x0, x1, y0, y1 = r.x0 - 0.5, r.x1 - 0.5, r.y0 - 0.5, r.y1 - 0.5
            series([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "region")
            self._overlay_items.append(dpg.add_plot_annotation(
                label="background", default_value=(x0, y0), offset=(30, -8),
                color=(255, 255, 255, 160), parent="img_plot"))
        if vm.region_corner is not None:
            series([vm.region_corner[0]], [vm.region_corner[1]], "drawing", scatter=True)
        if vm.settings.use_source:
            try:
                sx, sy = float(vm.settings.source_x), float(vm.settings.source_y)
                series([sx - 3, sx + 3, sx, sx], [sy, sy, sy - 3, sy + 3], "region",
                       segments=True)
            except ValueError:
                pass
        self._refresh_surface_list()
        dpg.set_value("mode", MODE_LABELS[vm.mode])
        # Panning with the left button would fight with clicking points in.
        pan = dpg.mvMouseButton_Left if vm.mode == "view" else dpg.mvMouseButton_Middle
        dpg.configure_item("img_plot", pan_button=pan)
        dpg.set_value("region_text", "Background region: none" if vm.region is None else
                      f"Background region: x {vm.region.x0}..{vm.region.x1 - 1}, y "
                      f"{vm.region.y0}..{vm.region.y1 - 1} ({vm.region.n_pixels} px)")

    def _refresh_surface_list(self) -> None:
        vm, s = self.vm, self._safe
        dpg.delete_item("surface_list", children_only=True)
        if not vm.surfaces:
            dpg.add_text("none yet: choose 'draw a line' and click twice across the plume",
                         parent="surface_list", color=GREY, wrap=LEFT_WIDTH - 20)
        for i, srf in enumerate(vm.surfaces):
            with dpg.group(horizontal=True, parent="surface_list"):
                dpg.add_input_text(default_value=srf.name, width=70, on_enter=True,
                                   user_data=i, callback=s(
                                       lambda sd, a, u: self.vm.rename_surface(u, a)))
                pts = " > ".join(f"({x:.0f},{y:.0f})" for x, y in srf.points)
                dpg.add_text(pts if len(pts) < 30 else pts[:27] + "...", color=_rgb(srf.colour))
                dpg.add_button(label="reverse", user_data=i,
                               callback=s(lambda sd, a, u: self.vm.reverse_surface(u)))
                dpg.add_button(label="delete", user_data=i,
                               callback=s(lambda sd, a, u: self.vm.delete_surface(u)))

    def _refresh_settings(self) -> None:
        """Push the form's values into the widgets (after open, or a pick on the image)."""
        st, vm = self.vm.settings, self.vm
        dpg.delete_item("species_group", children_only=True)
        for name, on in st.species.items():
            dpg.add_checkbox(label=name, default_value=on, parent="species_group",
                             user_data=name, callback=self._safe(self._on_species))
        for key in ("gas_temperature_K", "wind_speed_m_s", "exit_velocity_m_s",
                    "background_percentile", "distance_m", "ambient_temperature_K",
                    "pressure_Pa", "sigma_m", "frame_start", "frame_stop", "num_threads"):
            dpg.set_value(f"f_{key}", str(getattr(st, key)))
        dpg.set_value("f_gas_mode", st.gas_temperature_mode)
        dpg.set_value("f_velocity", st.velocity)
        dpg.set_value("f_averaging", st.averaging)
        dpg.set_value("f_background", st.background)
        dpg.set_value("f_use_source", st.use_source)
        dpg.set_value("f_source_x", st.source_x)
        dpg.set_value("f_source_y", st.source_y)
        dpg.set_value("f_keep_maps", st.keep_maps)
        if vm.recording is not None:
            vm.validate_settings()
        self._refresh_field_messages()

    def _refresh_field_messages(self) -> None:
        vm = self.vm
        hints = vm.settings.hints(vm.recording)
        errs = vm.field_errors
        for key in FIELDS:
            tag = f"msg_{key}"
            if not dpg.does_item_exist(tag):
                continue
            e = errs.get(key, "")
            dpg.set_value(tag, e if e else hints.get(key, ""))
            dpg.configure_item(tag, color=RED if e else GREY)
        st = vm.settings
        show = {"gas_temperature_K": st.gas_temperature_mode == "given",
                "wind_speed_m_s": st.velocity == "wind",
                "exit_velocity_m_s": st.velocity == "exit",
                "background_percentile": st.background == "percentile"}
        for key, on in show.items():
            dpg.configure_item(f"row_{key}", show=on)
            dpg.configure_item(f"msg_{key}", show=on)

    def _refresh_results(self) -> None:
        from .results_panel import build_rates_plot, build_results_panel

        build_results_panel(self, "results_group")
        build_rates_plot(self, "rates_y")
        self._fit_rates = 3  # new series are measured at the next frames: fit then
        species = self.vm.result_species()
        dpg.configure_item("d_overlay_species", items=species)
        if species:
            dpg.set_value("d_overlay_species", self.vm.overlay.species())

    def _refresh_playback(self) -> None:
        vm = self.vm
        if vm.recording is None:
            return
        if dpg.get_value("frame_slider") != vm.frame:
            dpg.set_value("frame_slider", vm.frame)
        dpg.configure_item("play_button", label="Pause" if vm.playing else "Play")
        dpg.set_value("time_text", f"t = {vm.frame_time_s:7.3f} s   frame {vm.frame + 1}/"
                                   f"{vm.n_frames}")

    def _refresh_progress(self) -> None:
        p = self.vm.progress()
        if p is None:
            dpg.configure_item("cancel_button", show=False)
            return
        running = p["state"] == "running"
        dpg.set_value("progress", p["fraction"])
        label = f"{self.vm.job.name}: {p['message']}" if running else \
            f"{self.vm.job.name} {p['state']} ({p['elapsed_s']:.1f} s)"
        dpg.configure_item("progress", overlay=label[:60])
        dpg.configure_item("cancel_button", show=running)
        dpg.configure_item("run_button", enabled=not running)
        dpg.configure_item("demo_button", enabled=not running)

    def _refresh_messages(self) -> None:
        msgs = self.vm.messages
        if len(msgs) == self._n_messages:
            return
        new = msgs[self._n_messages:]
        self._n_messages = len(msgs)
        last = msgs[-1]
        colour = {"error": RED, "warning": YELLOW}.get(last.level, GREEN)
        dpg.set_value("status_text", last.text[:200])
        dpg.configure_item("status_text", color=colour)
        errors = [m.text for m in new if m.level == "error"]
        if errors:
            self._popup("Something needs attention", "\n\n".join(errors[-3:]), "error")
        # Form problems are shown beside their fields.
        self._refresh_field_messages()

    def show_messages(self) -> None:
        """A window listing the last messages, newest first."""
        if dpg.does_item_exist("messages_window"):
            dpg.delete_item("messages_window")
        colours = {"error": RED, "warning": YELLOW, "info": (220, 220, 220)}
        with dpg.window(tag="messages_window", label="Messages", width=760, height=420,
                        pos=(200, 120)):
            for m in reversed(self.vm.messages[-60:]):
                stamp = time.strftime("%H:%M:%S", time.localtime(m.time_s))
                dpg.add_text(f"{stamp}  {m.text}", wrap=730, color=colours.get(m.level, GREY))

    def _popup(self, title: str, text: str, level: str) -> None:
        dpg.configure_item("popup", label=title)
        dpg.set_value("popup_text", text)
        dpg.configure_item("popup_text", color=RED if level == "error" else (230, 230, 230))
        vw = dpg.get_viewport_client_width()
        dpg.configure_item("popup", pos=(max(0, vw // 2 - 280), 180))
        dpg.show_item("popup")

    def _refresh_readout(self) -> None:
        vm = self.vm
        if self._unlock_axes:
            self._unlock_axes -= 1
            if self._unlock_axes == 0:  # set_axis_limits pins the axes; free them for zoom
                dpg.set_axis_limits_auto("img_x")
                dpg.set_axis_limits_auto("img_y")
        if vm.recording is None:
            return
        r = None
        if dpg.is_item_hovered("img_plot"):
            x, y = dpg.get_plot_mouse_pos()
            r = vm.readout(x, y)
        if r is not None:
            text = format_readout(r)
        else:
            d = vm.display
            lo, hi = vm.last_range
            rng = {v: k for k, v in RANGE_CHOICES.items()}[d.range_mode]
            text = (f"colours: channel {d.channel} {display.QUANTITY_LABELS[d.quantity]} "
                    f"{lo:.5g} .. {hi:.5g}, {rng}; point at the image for pixel values")
        if text != self._readout_text:
            self._readout_text = text
            dpg.set_value("readout", text)

    # ================================================================= handlers
    def on_open_dialog(self, *args) -> None:
        dpg.show_item("open_dialog")

    def _on_open_chosen(self, sender, app_data, user_data) -> None:
        sel = app_data.get("selections") or {}
        path = next(iter(sel.values()), None) or app_data.get("file_path_name", "")
        self.vm.open(path, background=True)

    def on_demo(self, *args) -> None:
        self.vm.open_demo()

    def on_run(self, *args) -> None:
        if self.vm.start_run():
            self.select_tab("results")

    def on_cancel(self, *args) -> None:
        self.vm.cancel_run()

    def on_export(self, kind: str) -> bool:
        folder = Path(dpg.get_value("export_dir") or ".").expanduser()
        stem = (dpg.get_value("export_stem") or "qogi").strip()
        vm = self.vm
        if kind == "window":
            if not folder.is_dir():
                return vm.log.error(f"could not save the screenshot: the folder {folder} does not "
                                 "exist")
            return self.screenshot(folder / f"{stem}_window.png")
        target = {"csv": f"{stem}.csv", "json": f"{stem}.json", "plots": f"{stem}_rates.png",
                  "frame": f"{stem}_frame.png", "report": f"{stem}_report.md",
                  "report_pdf": f"{stem}_report.pdf"}
        fn = {"csv": vm.export_csv, "json": vm.export_json, "plots": vm.export_plots,
              "frame": vm.export_frame, "report": vm.export_report,
              "report_pdf": vm.export_report}
        if kind == "all":
            return vm.export_all(folder, stem)
        return fn[kind](folder / target[kind])

    def press(self, tag, app_data=None) -> None:
        """Invoke a widget's callback as if the user had used it (scripts, tests);
        for value widgets ``app_data`` is the new value, set on the widget first."""
        if app_data is not None:
            dpg.set_value(tag, app_data)
        cb = dpg.get_item_callback(tag)
        if cb is None:
            raise ValueError(f"widget {tag!r} has no callback")
        cb(tag, app_data, dpg.get_item_user_data(tag))

    def screenshot(self, path) -> bool:
        """Save the whole window as PNG (written while the next frame renders)."""
        dpg.output_frame_buffer(file=str(path))
        self.vm.log.info(f"window screenshot written to {path}")
        return True

    def image_click(self, x: float, y: float, button: str = "left") -> bool:
        """A click on the image at pixel coordinates (what the mouse handler calls)."""
        tol = 6.0 * self._image_px_per_screen_px()
        return self.vm.click(x, y, button, tolerance_px=tol)

    def _image_px_per_screen_px(self) -> float:
        try:
            lo, hi = dpg.get_axis_limits("img_x")
            w = dpg.get_item_rect_size("img_plot")[0]
            return max(1e-3, (hi - lo) / max(1, w - 40))
        except Exception:  # before the first frame the plot has no size yet
            return 1.0

    def _mouse_click(self, button: str) -> None:
        if self.vm.recording is None or not dpg.is_item_hovered("img_plot"):
            return
        if self.vm.mode == "view" and button == "left":
            return  # look mode: clicks pan; selection is in edit mode
        if self.vm.mode == "edit" and self._over_drag_point():
            return
        x, y = dpg.get_plot_mouse_pos()
        self.image_click(x, y, button)

    def _over_drag_point(self) -> bool:
        x, y = dpg.get_plot_mouse_pos()
        tol = 8.0 * self._image_px_per_screen_px()
        return any(math.dist((x, y), p) <= tol for s in self.vm.surfaces for p in s.points)

    def _on_drag(self, sender, app_data, user_data) -> None:
        i, j = user_data
        x, y = dpg.get_value(sender)[:2]
        self.vm.move_vertex(i, j, x, y)

    def _on_key(self, sender, key, user_data) -> None:
        if not dpg.is_item_hovered("img_plot"):
            return  # keys act on the image only, never while typing in a field
        vm = self.vm
        if key == dpg.mvKey_Spacebar:
            vm.play()
        elif key == dpg.mvKey_Right:
            vm.step(1)
        elif key == dpg.mvKey_Left:
            vm.step(-1)
        elif key == dpg.mvKey_Return:
            vm.finish_drawing()
        elif key == dpg.mvKey_Escape:
            vm.cancel_drawing()
            vm.set_mode("view")
        elif key == dpg.mvKey_Back:
            vm.undo_point()
        elif key == dpg.mvKey_Delete and vm.selected is not None:
            vm.delete_surface(vm.selected)

    def set_mode(self, mode: str) -> None:
        """Switch what a click on the image does, and show the tab about it."""
        self.vm.set_mode(mode)
        self.select_tab("surfaces" if mode != "source" else "analysis")

    def select_tab(self, name: str) -> None:
        """Show a left-panel tab: recording, display, surfaces, analysis or results."""
        dpg.set_value("tabs", f"tab_{name}")

    def on_play(self, *args) -> None:
        self.vm.play()

    def _on_channel(self, sender, value, user_data) -> None:
        self.vm.set_display(channel=int(str(value).split(":", 1)[0]))

    def _on_fixed_range(self, *args) -> None:
        self.vm.set_display(fixed_min=dpg.get_value("d_min"), fixed_max=dpg.get_value("d_max"),
                            range_mode="fixed")

    def _on_fix_now(self, *args) -> None:
        lo, hi = self.vm.last_range
        self.vm.set_display(fixed_min=lo, fixed_max=hi, range_mode="fixed")

    def _on_field(self, key: str, value) -> None:
        self.vm.update_settings(**{key: value})
        self._refresh_field_messages()

    def _on_species(self, sender, value, name) -> None:
        species = dict(self.vm.settings.species)
        species[name] = bool(value)
        self._on_field("species", species)


def format_readout(r: dict) -> str:
    """One line describing the pixel under the cursor."""
    parts = [f"pixel ({r['x']}, {r['y']})"]
    for ch in r["channels"]:
        parts.append(f"{ch['name']}: {ch['radiance']:.5g} W/(m2 sr), "
                     f"{ch['temperature_K']:.2f} K")
    for sp, v in r.get("column_density_kg_m2", {}).items():
        parts.append(f"{sp} {v * 1e3:.3g} g/m2")
    if "velocity_m_s" in r:
        u, v = r["velocity_m_s"]
        parts.append(f"velocity ({u:.2f}, {-v:.2f}) m/s (right, up)")
    if "status" in r:
        parts.append(f"status {r['status']}")
    return " | ".join(parts)


HELP_TEXT = """Image: mouse wheel zooms, dragging pans (look mode), double-click fits.
Surfaces tab: choose what a click does. 'draw a line': click the two ends. 'draw a polyline': click the points, then right-click (or Enter, or 'Finish surface'). 'edit': drag the points. The arrow on each surface shows the direction counted positive (the left-hand side walking from its first to its last point); 'reverse' flips it.
Keys (mouse over the image): Space play/pause, Left/Right step, Enter finish, Backspace undo point, Esc stop drawing, Delete remove the selected surface.
Analysis tab: each field says what it accepts; problems show in red beside it. Run starts the quantification in the background; the window stays usable and Cancel keeps the frames finished so far.
Results tab: rates per surface and species, side by side, and the exports."""


class NoDisplayError(RuntimeError):
    """There is no screen to open the window on."""


def check_display() -> None:
    """Raise :class:`NoDisplayError` with the fix when no X display can be
    opened (on Linux Dear PyGui would abort the process instead of raising)."""
    if not sys.platform.startswith("linux"):
        return
    name = os.environ.get("DISPLAY", "")
    if not name:
        raise NoDisplayError(
            "no display: DISPLAY is not set. Run the viewer on a desktop session, or "
            "under a virtual X server: xvfb-run -s '-screen 0 1600x1000x24' qogi gui")
    import ctypes
    import ctypes.util

    lib = ctypes.util.find_library("X11")
    if lib is None:
        raise NoDisplayError("libX11 is missing; install it (Debian: libx11-6)")
    x11 = ctypes.CDLL(lib)
    x11.XOpenDisplay.restype = ctypes.c_void_p
    x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
    x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
    d = x11.XOpenDisplay(name.encode())
    if not d:
        raise NoDisplayError(f"cannot open the X display {name!r}: is the X server running and "
                             "may this user connect to it (xauth)?")
    x11.XCloseDisplay(d)


def run(path=None, width: int = 1440, height: int = 900, scene: Optional[dict] = None) -> int:
    """Open the window (and ``path`` if given, with the camera file's
    ``scene`` facts if given: remembered for it); returns 0 when it is
    closed. Raises :class:`NoDisplayError` when there is no screen."""
    check_display()
    app = App(ViewModel(), width, height)
    app.build()
    if path and scene:
        app.vm.store.set_scene(path, scene)
    if path:
        app.vm.open(path, background=True)
    try:
        app.loop()
    finally:
        app.close()
    return 0
