"""Drive the real viewer window end to end (run by test_window.py under Xvfb).

Opens the window, loads the demo scene with the demo button's handler, plays
it, draws control surfaces through the image-click handler (the one the mouse
handler calls, with pixel coordinates), runs the real quantification to the
end while the window keeps drawing, exports everything, and saves a
screenshot of each main state (Dear PyGui's frame buffer).

Usage: python tests/gui/window_driver.py OUT_DIR
Writes OUT_DIR/viewer_*.png, OUT_DIR/export/* and OUT_DIR/state.json.
"""

from __future__ import annotations

import json
import math
import sys
import time
from pathlib import Path

import dearpygui.dearpygui as dpg

from qogi_gui import demo, results
from qogi_gui.app import MODE_LABELS, App
from qogi_gui.viewmodel import ViewModel

WIDTH, HEIGHT = 1440, 900


class XInput:
    """Real mouse and keyboard events through the X server's XTEST extension
    (what a user's hand produces), to drive the window's own input handlers."""

    def __init__(self, driver: Driver):
        import ctypes
        import os

        self.d = driver
        self.x11 = ctypes.CDLL("libX11.so.6")
        self.xt = ctypes.CDLL("libXtst.so.6")
        self.x11.XOpenDisplay.restype = ctypes.c_void_p
        self.x11.XOpenDisplay.argtypes = [ctypes.c_char_p]
        self.x11.XFlush.argtypes = [ctypes.c_void_p]
        self.x11.XCloseDisplay.argtypes = [ctypes.c_void_p]
        self.x11.XKeysymToKeycode.argtypes = [ctypes.c_void_p, ctypes.c_ulong]
        self.x11.XStringToKeysym.restype = ctypes.c_ulong
        self.x11.XStringToKeysym.argtypes = [ctypes.c_char_p]
        self.xt.XTestFakeMotionEvent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_int,
            ctypes.c_ulong,
        ]
        self.xt.XTestFakeButtonEvent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_ulong,
        ]
        self.xt.XTestFakeKeyEvent.argtypes = [
            ctypes.c_void_p,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_ulong,
        ]
        self.dpy = self.x11.XOpenDisplay(os.environ["DISPLAY"].encode())
        if not self.dpy:
            raise RuntimeError("cannot open the X display for input events")
        self.pos = (0, 0)

    def close(self):
        self.x11.XCloseDisplay(self.dpy)

    def _sync(self, frames: int = 3):
        self.x11.XFlush(self.dpy)
        self.d.frames(frames)

    def move(self, sx: float, sy: float, frames: int = 3):
        """Move the pointer to screen position (sx, sy)."""
        self.pos = (int(round(sx)), int(round(sy)))
        self.xt.XTestFakeMotionEvent(self.dpy, -1, self.pos[0], self.pos[1], 0)
        self._sync(frames)

    def button(self, number: int, down: bool):
        self.xt.XTestFakeButtonEvent(self.dpy, number, bool(down), 0)
        self._sync()

    def click(self, number: int = 1):
        self.button(number, True)
        self.button(number, False)

    def key(self, name: str):
        code = self.x11.XKeysymToKeycode(self.dpy, self.x11.XStringToKeysym(name.encode()))
        for down in (True, False):
            self.xt.XTestFakeKeyEvent(self.dpy, code, down, 0)
            self._sync()

    def to_pixel(self, x: float, y: float):
        """Put the pointer over image pixel coordinates (x, y), steering by what
        the plot reports under the pointer; returns the plot's reading there."""
        vx, vy = dpg.get_viewport_pos()
        rx, ry = dpg.get_item_rect_min("img_plot")
        w, h = dpg.get_item_rect_size("img_plot")
        sx, sy = vx + rx + w / 2, vy + ry + h / 2
        self.move(sx, sy)
        p0 = dpg.get_plot_mouse_pos()
        self.move(sx + 100, sy + 100)
        p1 = dpg.get_plot_mouse_pos()
        kx, ky = (p1[0] - p0[0]) / 100.0, (p1[1] - p0[1]) / 100.0  # image px per screen px
        sx, sy = sx + (x - p0[0]) / kx, sy + (y - p0[1]) / ky
        for _ in range(4):
            self.move(sx, sy)
            px, py = dpg.get_plot_mouse_pos()
            if abs(px - x) <= abs(kx) and abs(py - y) <= abs(ky):
                break
            sx, sy = sx + (x - px) / kx, sy + (y - py) / ky
        return tuple(dpg.get_plot_mouse_pos())


class Driver:
    def __init__(self, out: Path, vm: ViewModel):
        self.out = out
        self.app = App(vm, WIDTH, HEIGHT, vsync=False)
        self.vm = vm
        self.shots = []
        self.frame_gaps = []

    def frames(self, n: int = 3) -> None:
        for _ in range(n):
            self._frame()

    def _frame(self) -> None:
        t = time.monotonic()
        self.app.frame()
        self.frame_gaps.append(time.monotonic() - t)

    def until(self, cond, timeout_s: float, what: str) -> int:
        """Draw frames until ``cond()``; returns how many were drawn."""
        end = time.monotonic() + timeout_s
        n = 0
        while not cond():
            if time.monotonic() > end:
                raise TimeoutError(
                    f"timed out after {timeout_s:.0f} s waiting for {what}; "
                    f"last message: {self.vm.last_message}"
                )
            self._frame()
            n += 1
        return n

    def shot(self, name: str) -> None:
        path = self.out / name
        if path.exists():
            path.unlink()
        self.app.screenshot(path)
        self.until(path.exists, 20, f"the screenshot {name}")
        self.frames(2)
        self.shots.append(name)


def run(out: Path, vm: ViewModel = None) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    d = Driver(out, vm if vm is not None else ViewModel())
    app, vm = d.app, d.vm
    app.build()
    d.frames(3)

    # 1. The demo scene with one click, then play it.
    app.on_demo()
    d.until(lambda: vm.recording is not None and not vm.busy, 900, "the demo scene")
    app.press("play_button")
    d.frames(20)
    app.press("speed", "2x")
    d.frames(10)
    app.press("play_button")
    # The display controls, as a user would set them.
    app.select_tab("display")
    app.press("d_quantity", "radiometric temperature [K]")
    app.press("d_range", "auto (this frame)")
    app.press("d_cmap", "gray")
    d.frames(2)
    app.press("d_fix_now")
    app.press("d_min", 280.0)
    app.press("d_cmap", "inferno")
    app.press("d_range", "auto (whole recording)")
    app.press("frame_slider", vm.n_frames // 2)
    app.select_tab("recording")
    d.frames(3)
    d.shot("viewer_demo.png")

    # 2. Surfaces across the plume above its source: S1 left to right (upward
    # flow positive), S2 the same line right to left (upward flow negative),
    # S3 a polyline higher up; and a background region in a gas-free corner.
    sx, sy = demo.source_pixel()
    w = vm.recording.width
    half = 0.3 * w
    y1 = sy - 0.25 * (sy + 0.5)
    # S1 and S3 with real mouse clicks (XTEST), S2 through the click handler.
    app.select_tab("surfaces")
    mouse = XInput(d)
    app.press("mode", MODE_LABELS["line"])
    aimed = []
    for x, y in ((sx - half, y1), (sx + half, y1)):
        aimed.append(mouse.to_pixel(x, y))
        mouse.click(1)
    app.image_click(sx + half, y1 - 8)
    app.image_click(sx - half, y1 - 8)
    app.press("mode", MODE_LABELS["polyline"])
    y3 = sy - 0.55 * (sy + 0.5)
    for x, y in ((sx - half, y3 + 6), (sx, y3), (sx + half, y3 + 6)):
        aimed.append(mouse.to_pixel(x, y))
        mouse.click(1)
    mouse.click(3)  # right button ends the polyline
    # Edit: drag S3's middle point 5 px up with the mouse.
    app.press("mode", MODE_LABELS["edit"])
    d.frames(2)
    bx, by = vm.surfaces[2].points[1]
    mouse.to_pixel(bx, by)
    mouse.button(1, True)
    start = mouse.pos
    for k in range(1, 6):
        mouse.move(start[0], start[1] - 2 * k)
    mouse.button(1, False)
    dragged = {"before": [bx, by], "after": list(vm.surfaces[2].points[1])}
    app.press("mode", MODE_LABELS["view"])
    mouse.close()
    d.frames(3)
    d.shot("viewer_surfaces.png")
    drawn = [{"name": s.name, "points": s.points} for s in vm.surfaces]

    # 3. The analysis form, then run in the background.
    app.select_tab("analysis")
    app.press("f_velocity", "wind")  # shows the wind-speed field
    app.press("f_gas_mode", "given")  # shows the gas-temperature field
    d.frames(2)
    app.press("f_line_shape_wing", "hapi")  # hides the wing-width field
    app.press("f_exit_temperature_K", "900.5")  # outside [150, 900] K: a message beside it
    d.frames(2)
    field_message = dpg.get_value("msg_exit_temperature_K")
    app.press("f_exit_temperature_K", "")
    app.press("f_line_shape_wing", "fixed")
    app.press("f_velocity", "fluid")
    app.press("f_gas_mode", "ambient")
    d.frames(3)
    d.shot("viewer_analysis.png")
    app.on_run()
    fractions = set()
    running_frames = 0
    shot_taken = False
    while vm.busy:
        d._frame()
        running_frames += 1
        p = vm.progress()
        fractions.add(round(p["fraction"], 3))
        if not shot_taken and p["fraction"] >= 0.3:
            d.shot("viewer_running.png")
            shot_taken = True
    d.frames(5)
    assert vm.result is not None, f"no result; last message: {vm.last_message}"

    # 4. Results: overlay, vectors, rates; then export everything.
    app.select_tab("results")
    vm.seek(vm.n_frames // 2)
    app.press("d_next_maps")  # a frame whose per-pixel maps were kept
    d.frames(5)
    d.shot("viewer_results.png")
    export = out / "export"
    export.mkdir(exist_ok=True)
    from dearpygui import dearpygui as _dpg

    _dpg.set_value("export_dir", str(export))
    exported = all(app.on_export(kind) for kind in ("csv", "json", "plots", "frame", "report"))
    exported = app.on_export("all") and exported
    app.press("d_overlay_cmap", "turbo")
    app.press("d_vectors", False)
    app.press("d_vectors", True)
    app.show_messages()
    d.frames(2)

    rows = [
        {
            "surface": r.surface,
            "species": r.species,
            "mean_kg_h": r.mean_kg_h,
            "ci90_kg_h": list(r.ci90_kg_h),
            "truth_kg_h": r.truth_kg_h,
            "n_frames": r.n_frames,
            "n_frames_valid": r.n_frames_valid,
        }
        for r in results.rate_rows(vm.result)
    ]
    state = {
        "results_texts": _texts("results_group"),
        "field_message": field_message,
        "line_shape": vm.result_settings.get("line_shape"),
        "shots": d.shots,
        "drawn": drawn,
        "aimed": aimed,
        "drag": dragged,
        "rows": rows,
        "exported": exported,
        "running_frames": running_frames,
        "distinct_progress": len(fractions),
        "max_frame_s": max(d.frame_gaps),
        "fps": app.fps,
        "messages": [(m.level, m.text) for m in vm.messages],
        "recording": vm.recording_path,
        "n_frames": vm.n_frames,
        "overlay_shown": vm.render_overlay() is not None,
        "vectors": int(len(vm.vectors()[0])),
    }
    (out / "state.json").write_text(json.dumps(state, indent=1, default=_json_default))
    app.close()
    return state


def _texts(item) -> list:
    """The text of every text widget under ``item``, in order."""
    out = []
    for slot in dpg.get_item_children(item).values():
        for child in slot:
            if dpg.get_item_type(child) == "mvAppItemType::mvText":
                out.append(dpg.get_value(child))
            out += _texts(child)
    return out


def _json_default(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return str(o)


if __name__ == "__main__":
    run(Path(sys.argv[1]))
