"""Speed of the viewer's playback on a 320x256, 4-channel, 100 Hz recording.

Figures, each against a baseline timed in the same run:
- baseline: raw frame reads from the HDF5 recording (``Recording.frames``,
  all four channels), frames/s;
- the view-model's display path per frame (read, convert the shown channel,
  robust colour mapping into the RGBA buffer), shown as band radiance and as
  radiometric temperature, frames/s and ratio to the raw read rate;
- the real window (Dear PyGui, 1440x900, under Xvfb with Mesa's llvmpipe
  software OpenGL when no display is set) playing the recording in real time
  (1x = 100 recording frames/s): frames drawn per second against two
  baselines timed in the same run, a bare Dear PyGui window of the same size
  (one line of text: the display's own floor) and the viewer with the video
  paused; recording frames shown per second, and the gaps between drawn
  frames. Playback
  follows the recording's clock and shows the newest due frame at each draw,
  so a display slower than 100 Hz skips frames but never falls behind.

Run: .venv/bin/python benchmarks/bench_gui.py
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import qogi
from qogi.physics.radiometry import temperature_to_radiance

T, C, H, W, RATE = 300, 4, 256, 320, 100.0


def make_recording(path: Path) -> None:
    cam = qogi.camera_preset("fast-m150")
    rng = np.random.default_rng(0)
    y, x = np.mgrid[0:H, 0:W]
    with qogi.RecordingWriter(
        path,
        quantity="radiance",
        camera=qogi.Camera(
            cam.name, cam.ifov_rad, cam.channels, frame_rate_hz=RATE, netd_K=cam.netd_K
        ),
        scene=qogi.Scene(3.0, 293.15, 101325.0, species=("CH4", "CO2")),
        frame_shape=(C, H, W),
    ) as wr:
        for i in range(T):
            temp = (
                288.0
                + 0.01 * x
                + 6.0 * np.exp(-((x - 160) ** 2 + (y - 200 + i * 0.5) ** 2) / 400.0)
                + rng.normal(0, 0.02, (H, W))
            )
            frame = temperature_to_radiance(np.broadcast_to(temp, (C, H, W)), cam.channels)
            wr.append(frame.astype(np.float32), i / RATE)


def rate(fn, n: int) -> float:
    fn(0)
    t0 = time.perf_counter()
    for i in range(n):
        fn(i)
    return n / (time.perf_counter() - t0)


def start_xvfb():
    exe = shutil.which("Xvfb")
    if exe is None:
        return None, None
    r, w = os.pipe()
    proc = subprocess.Popen(
        [exe, "-displayfd", str(w), "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
        pass_fds=(w,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()
    return proc, f":{number}"


BARE_WINDOW = """
import sys, time
import dearpygui.dearpygui as dpg
dpg.create_context()
dpg.create_viewport(title="bare", width=1440, height=900, vsync=False)
with dpg.window(tag="w"):
    dpg.add_text("bare window")
dpg.set_primary_window("w", True)
dpg.setup_dearpygui()
dpg.show_viewport()
for _ in range(10):
    dpg.render_dearpygui_frame()
n, t0 = 0, time.perf_counter()
while time.perf_counter() - t0 < float(sys.argv[1]):
    dpg.render_dearpygui_frame()
    n += 1
print(n / (time.perf_counter() - t0))
dpg.destroy_context()
"""


def bare_window_fps(seconds: float = 5.0) -> float:
    """Frames/s of a bare Dear PyGui window of the viewer's size (own process)."""
    out = subprocess.run(
        [sys.executable, "-c", BARE_WINDOW, str(seconds)],
        capture_output=True,
        text=True,
        check=True,
        timeout=120,
    )
    return float(out.stdout.strip().splitlines()[-1])


def window_playback(path: Path, seconds: float = 5.0) -> dict:
    """Play the recording in the real window; frames drawn and frames shown per second."""
    from qogi_gui.app import App
    from qogi_gui.store import UserStore
    from qogi_gui.viewmodel import ViewModel

    with tempfile.TemporaryDirectory() as cfg:
        vm = ViewModel(store=UserStore(cfg), demo_provider=lambda p: "")
        app = App(vm, 1440, 900, vsync=False)
        app.build()
        vm.open(path)
        for _ in range(10):
            app.frame()
        vm.set_speed(1.0)
        out = {}
        for playing in (False, True):
            vm.play(playing)
            shown, drawn, gaps, last_frame = 0, 0, [], vm.frame
            t0 = t = time.perf_counter()
            while t - t0 < seconds:
                app.frame()
                now = time.perf_counter()
                gaps.append(now - t)
                t = now
                drawn += 1
                if vm.frame != last_frame:
                    shown += 1
                    last_frame = vm.frame
            elapsed = t - t0
            out["playing" if playing else "paused"] = {
                "fps": drawn / elapsed,
                "shown": shown / elapsed,
                "max_gap_ms": 1e3 * max(gaps),
                "p95_gap_ms": 1e3 * float(np.percentile(gaps, 95)),
            }
        app.close()
    return out


def main():
    from qogi_gui.store import UserStore
    from qogi_gui.viewmodel import ViewModel

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.h5"
        make_recording(path)
        rec = qogi.open_recording(path)
        raw = rate(lambda i: rec.frames(i % T, i % T + 1), 300)
        print(
            f"recording {T} x {C} x {H}x{W} at {RATE:g} Hz; baseline raw frame read "
            f"(Recording.frames, 4 channels): {raw:.0f} frames/s"
        )
        vm = ViewModel(store=UserStore(Path(tmp) / "cfg"), demo_provider=lambda p: "")
        vm.open(path)
        for quantity in ("radiance", "radiometric_temperature"):
            for rng_mode in ("recording", "frame"):
                vm.set_display(quantity=quantity, range_mode=rng_mode, channel=2)

                def show(i):
                    vm.seek(i % T)
                    vm.render()

                r = rate(show, 300)
                print(
                    f"view-model display path ({quantity}, {rng_mode} range): {r:.0f} "
                    f"frames/s = {r / raw:.2f} x the raw read rate "
                    f"({1e3 / r:.2f} ms per frame; {r / RATE:.1f} x the 100 Hz need)"
                )
        vm.close()
        rec.close()

        proc, display = None, os.environ.get("DISPLAY")
        if not display:
            proc, display = start_xvfb()
        if display is None:
            print("window playback: skipped (no DISPLAY and no Xvfb)")
            return
        os.environ["DISPLAY"] = display
        try:
            bare = bare_window_fps()
            res = window_playback(path)
        finally:
            if proc is not None:
                proc.terminate()
                proc.wait(10)
        where = "Xvfb + Mesa llvmpipe (software OpenGL)" if proc is not None else display
        idle, play = res["paused"], res["playing"]
        print(
            f"window 1440x900 on {where}: baseline 1, bare Dear PyGui window: {bare:.1f} "
            f"frames drawn/s; baseline 2, the viewer with the video paused: {idle['fps']:.1f} "
            f"frames drawn/s = {idle['fps'] / bare:.2f} x the bare window"
        )
        print(
            f"window playing at 1x: {play['fps']:.1f} frames drawn/s = "
            f"{play['fps'] / bare:.2f} x the bare window, "
            f"{play['fps'] / idle['fps']:.2f} x the paused viewer; {play['shown']:.1f} new "
            f"recording frames shown/s (recording: {RATE:g}/s, the rest skipped to keep real "
            f"time); gap between drawn frames p95 {play['p95_gap_ms']:.0f} ms, max "
            f"{play['max_gap_ms']:.0f} ms"
        )


if __name__ == "__main__":
    sys.exit(main())
