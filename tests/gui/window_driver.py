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
from qogi_gui.app import App
from qogi_gui.viewmodel import ViewModel

WIDTH, HEIGHT = 1440, 900


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
                raise TimeoutError(f"timed out after {timeout_s:.0f} s waiting for {what}; "
                                   f"last message: {self.vm.last_message}")
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
    app.select_tab("surfaces")
    app.set_mode("line")
    app.image_click(sx - half, y1)
    app.image_click(sx + half, y1)
    app.image_click(sx + half, y1 - 4)
    app.image_click(sx - half, y1 - 4)
    app.set_mode("polyline")
    y3 = sy - 0.55 * (sy + 0.5)
    for x, y in ((sx - half, y3 + 6), (sx, y3), (sx + half, y3 + 6)):
        app.image_click(x, y)
    app.image_click(0, 0, "right")
    app.set_mode("view")
    d.frames(3)
    d.shot("viewer_surfaces.png")
    drawn = [{"name": s.name, "points": s.points} for s in vm.surfaces]

    # 3. The analysis form, then run in the background.
    app.select_tab("analysis")
    app.press("f_velocity", "wind")        # shows the wind-speed field
    app.press("f_gas_mode", "given")       # shows the gas-temperature field
    d.frames(2)
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

    rows = [{"surface": r.surface, "species": r.species, "mean_kg_h": r.mean_kg_h,
             "ci90_kg_h": list(r.ci90_kg_h), "truth_kg_h": r.truth_kg_h,
             "n_frames": r.n_frames, "n_frames_valid": r.n_frames_valid}
            for r in results.rate_rows(vm.result)]
    state = {
        "shots": d.shots, "drawn": drawn, "rows": rows, "exported": exported,
        "running_frames": running_frames, "distinct_progress": len(fractions),
        "max_frame_s": max(d.frame_gaps), "fps": app.fps,
        "messages": [(m.level, m.text) for m in vm.messages],
        "recording": vm.recording_path, "n_frames": vm.n_frames,
        "overlay_shown": vm.render_overlay() is not None,
        "vectors": int(len(vm.vectors()[0])),
    }
    (out / "state.json").write_text(json.dumps(state, indent=1, default=_json_default))
    app.close()
    return state


def _json_default(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    return str(o)


if __name__ == "__main__":
    run(Path(sys.argv[1]))
