"""The Dear PyGui window of the viewer.

Widgets only: every user action is forwarded to :class:`~qogi_gui.viewmodel.ViewModel`
and the window redraws what the view-model holds (it watches ``vm.rev`` to
redraw only what changed). :class:`App` lays out one panel object per part
of the window (:mod:`qogi_gui.widgets`) and runs the render loop
(:meth:`App.frame`), with Dear PyGui's callbacks run on this same thread, so
the view-model is only ever touched from one thread; long work runs in the
view-model's background jobs and the loop keeps drawing.

Every callback goes through :meth:`App.safe`: an unexpected exception
becomes a message in the window (and a traceback on the terminal), never a
crash.

The handlers named ``on_*`` and :meth:`App.image_click` are what the widgets
call; scripts and the smoke test call them too.
"""

from __future__ import annotations

import os
import sys
import time
import traceback
from typing import Optional

import dearpygui.dearpygui as dpg

from .viewmodel import ViewModel
from .widgets.analysis_tab import AnalysisTab
from .widgets.dialogs import Dialogs
from .widgets.display_tab import DisplayTab
from .widgets.image_view import ImageView, format_readout
from .widgets.playback_bar import PlaybackBar
from .widgets.recording_tab import RecordingTab
from .widgets.results_tab import ResultsTab
from .widgets.status_bar import StatusBar
from .widgets.surfaces_tab import MODE_LABELS, SurfacesTab
from .widgets.theme import LEFT_WIDTH, build_colormaps, build_themes

__all__ = ["App", "run", "check_display", "NoDisplayError", "MODE_LABELS", "format_readout"]


class App:
    """The viewer window around a :class:`ViewModel`.

    Parameters
    ----------
    vm : ViewModel, optional
    width, height : int, px
        Initial window size.
    """

    def __init__(
        self,
        vm: Optional[ViewModel] = None,
        width: int = 1440,
        height: int = 900,
        vsync: bool = True,
    ):
        self.vm = vm if vm is not None else ViewModel()
        self.width, self.height = width, height
        self.vsync = vsync
        self.themes: dict = {}
        self.recording_tab = RecordingTab(self)
        self.display_tab = DisplayTab(self)
        self.surfaces_tab = SurfacesTab(self)
        self.analysis_tab = AnalysisTab(self)
        self.results_tab = ResultsTab(self)
        self.image = ImageView(self)
        self.playback = PlaybackBar(self)
        self.status = StatusBar(self)
        self.dialogs = Dialogs(self)
        self._seen = {}
        self._frames_drawn = 0
        self._video_frames = 0
        self._fps_t0 = time.monotonic()
        self.fps = 0.0
        self.video_fps = 0.0
        self._last_shown = None
        self._fit_rates = 0

    # ================================================================= safety
    def safe(self, fn):
        """Wrap a callback so that any exception becomes a message in the window."""

        def cb(sender=None, app_data=None, user_data=None):
            try:
                return fn(sender, app_data, user_data)
            except Exception as e:  # noqa: BLE001 - the window must survive any handler
                traceback.print_exc()
                self.vm.log.error(
                    f"internal error in the viewer ({type(e).__name__}: {e}); "
                    "details were printed to the terminal"
                )

        return cb

    # ================================================================= build
    def build(self) -> None:
        """Create the context, the widgets and the viewport (shown)."""
        dpg.create_context()
        dpg.configure_app(manual_callback_management=True)
        dpg.create_viewport(
            title="qogi viewer",
            width=self.width,
            height=self.height,
            min_width=900,
            min_height=600,
            vsync=self.vsync,
        )
        self.themes = build_themes()
        build_colormaps()
        dpg.add_texture_registry(tag="textures")
        with dpg.window(tag="main", no_scrollbar=True):
            self._build_menu()
            with dpg.group(horizontal=True):
                with dpg.child_window(width=LEFT_WIDTH, tag="left", border=False):
                    self._build_tabs()
                with dpg.child_window(width=-1, tag="right", border=False, no_scrollbar=True):
                    self.image.build()
                    self.playback.build()
                    self.image.build_readout()
                    self.results_tab.build_rates_plot()
            self.status.build()
        self.dialogs.build()
        self.image.build_handlers()
        self.recording_tab.refresh_recent()
        dpg.set_viewport_resize_callback(self.safe(lambda *a: self._layout()))
        dpg.setup_dearpygui()
        dpg.show_viewport()
        dpg.set_primary_window("main", True)
        self._layout()

    def _build_menu(self) -> None:
        s = self.safe
        with dpg.menu_bar():
            with dpg.menu(label="File"):
                dpg.add_menu_item(label="Open recording...", callback=s(self.on_open_dialog))
                dpg.add_menu_item(label="Load the demo scene", callback=s(self.on_demo))
                dpg.add_menu(label="Recent", tag="recent_menu")
                dpg.add_separator()
                dpg.add_menu_item(
                    label="Export all results...", callback=s(lambda *a: self.on_export("all"))
                )
                dpg.add_menu_item(
                    label="Save window screenshot", callback=s(lambda *a: self.on_export("window"))
                )
                dpg.add_separator()
                dpg.add_menu_item(label="Quit", callback=s(lambda *a: dpg.stop_dearpygui()))
            with dpg.menu(label="View"):
                dpg.add_menu_item(label="Fit image", callback=s(lambda *a: self.fit_image()))
            with dpg.menu(label="Help"):
                dpg.add_menu_item(
                    label="Mouse and keys",
                    callback=s(lambda *a: self.dialogs.popup("Mouse and keys", HELP_TEXT, "info")),
                )

    def _build_tabs(self) -> None:
        with dpg.tab_bar(tag="tabs"):
            for name, label, panel in (
                ("recording", "Recording", self.recording_tab),
                ("display", "Display", self.display_tab),
                ("surfaces", "Surfaces", self.surfaces_tab),
                ("analysis", "Analysis", self.analysis_tab),
                ("results", "Results", self.results_tab),
            ):
                with dpg.tab(label=label, tag=f"tab_{name}"):
                    panel.build()

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
        except Exception as e:  # noqa: BLE001 - keep the window alive whatever a redraw hits
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
        """Take in finished jobs and the playback clock, then redraw each
        panel whose part of the view-model changed."""
        vm = self.vm
        vm.work.poll()
        vm.player.tick()
        if self._changed("recording"):
            self._new_recording()
        if self._changed("settings"):
            self.analysis_tab.refresh()
        if self._changed("scene_request"):
            self.dialogs.refresh_scene_form()
        result_changed = self._changed("result")
        if result_changed:
            self.results_tab.refresh()
            self._fit_rates = 3  # new series are measured at the next frames: fit then
            self.display_tab.new_result()
        display_changed = self._changed("display")
        if vm.recording is not None:
            shown = (vm.player.frame, vm.rev["display"], vm.rev["result"], vm.rev["recording"])
            if shown != self._last_shown:
                self._last_shown = shown
                self.image.upload_frame()
                self._video_frames += 1
            if display_changed:
                self.display_tab.refresh()
        if self._changed("surfaces") or result_changed:
            self.image.refresh_overlays()
            self.surfaces_tab.refresh()
        if self._fit_rates:
            self._fit_rates -= 1
            dpg.fit_axis_data("rates_x")
            dpg.fit_axis_data("rates_y")
        self.playback.refresh()
        self.status.refresh_progress()
        if self.status.refresh_messages():
            self.analysis_tab.refresh_messages()  # form problems are shown beside their fields
        self.image.refresh_readout()
        now = time.monotonic()
        if now - self._fps_t0 >= 1.0:
            dt = now - self._fps_t0
            self.fps = self._frames_drawn / dt
            self.video_fps = self._video_frames / dt
            self._frames_drawn = self._video_frames = 0
            self._fps_t0 = now
            self.status.show_fps(self.fps, self.video_fps)

    def _new_recording(self) -> None:
        self.recording_tab.refresh()
        rec = self.vm.recording
        if rec is None:
            return
        self.playback.new_recording(rec)
        self.display_tab.new_recording(rec)
        self.image.new_recording(rec)
        self._last_shown = None
        self.display_tab.refresh()
        self.image.fit_image()

    # ================================================================= handlers
    def on_open_dialog(self, *args) -> None:
        self.recording_tab.on_open_dialog()

    def on_demo(self, *args) -> None:
        self.recording_tab.on_demo()

    def on_run(self, *args) -> None:
        self.analysis_tab.on_run()

    def on_cancel(self, *args) -> None:
        self.status.on_cancel()

    def on_play(self, *args) -> None:
        self.playback.on_play()

    def on_export(self, kind: str) -> bool:
        """See :meth:`qogi_gui.widgets.results_tab.ResultsTab.on_export`."""
        return self.results_tab.on_export(kind)

    def image_click(self, x: float, y: float, button: str = "left") -> bool:
        """A click on the image at pixel coordinates (what the mouse handler calls)."""
        return self.image.image_click(x, y, button)

    def fit_image(self) -> None:
        self.image.fit_image()

    def show_messages(self) -> None:
        """A window listing the last messages, newest first."""
        self.status.show_messages()

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

    def set_mode(self, mode: str) -> None:
        """Switch what a click on the image does, and show the tab about it."""
        self.vm.editor.set_mode(mode)
        self.select_tab("surfaces" if mode != "source" else "analysis")

    def select_tab(self, name: str) -> None:
        """Show a left-panel tab: recording, display, surfaces, analysis or results."""
        dpg.set_value("tabs", f"tab_{name}")


HELP_TEXT = "\n".join(
    [
        ("Image: mouse wheel zooms, dragging pans (look mode), double-click fits."),
        (
            "Surfaces tab: choose what a click does. 'draw a line': click the two ends. 'draw"
            " a polyline': click the points, then right-click (or Enter, or 'Finish "
            "surface'). 'edit': drag the points. The arrow on each surface shows the "
            "direction counted positive (the left-hand side walking from its first to its "
            "last point); 'reverse' flips it."
        ),
        (
            "Keys (mouse over the image): Space play/pause, Left/Right step, Enter finish, "
            "Backspace undo point, Esc stop drawing, Delete remove the selected surface."
        ),
        (
            "Analysis tab: each field says what it accepts; problems show in red beside it. "
            "Run starts the quantification in the background; the window stays usable and "
            "Cancel keeps the frames finished so far."
        ),
        ("Results tab: rates per surface and species, side by side, and the exports."),
    ]
)


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
            "under a virtual X server: xvfb-run -s '-screen 0 1600x1000x24' qogi gui"
        )
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
        raise NoDisplayError(
            f"cannot open the X display {name!r}: is the X server running and "
            "may this user connect to it (xauth)?"
        )
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
