"""The controls below the image: step, play/pause, frame slider, speed, time."""

from __future__ import annotations

import dearpygui.dearpygui as dpg

from ..panels.playback import SPEEDS
from .panel import Panel

__all__ = ["PlaybackBar"]


class PlaybackBar(Panel):
    def build(self) -> None:
        s, player = self.app.safe, self.vm.player
        with dpg.group(horizontal=True):
            dpg.add_button(label="|<", callback=s(lambda *a: player.step(-player.frame)))
            dpg.add_button(label="<", callback=s(lambda *a: player.step(-1)))
            dpg.add_button(label="Play", tag="play_button", width=60, callback=s(self.on_play))
            dpg.add_button(label=">", callback=s(lambda *a: player.step(1)))
            dpg.add_slider_int(
                tag="frame_slider",
                width=-330,
                min_value=0,
                max_value=0,
                callback=s(lambda sd, a, u: player.seek(a)),
            )
            dpg.add_combo(
                [f"{v:g}x" for v in SPEEDS],
                tag="speed",
                width=70,
                default_value="1x",
                callback=s(lambda sd, a, u: player.set_speed(a.rstrip("x"))),
            )
            dpg.add_text("", tag="time_text")

    def new_recording(self, rec) -> None:
        dpg.configure_item("frame_slider", max_value=max(0, rec.n_frames - 1))

    def refresh(self) -> None:
        player = self.vm.player
        if self.vm.recording is None:
            return
        if dpg.get_value("frame_slider") != player.frame:
            dpg.set_value("frame_slider", player.frame)
        dpg.configure_item("play_button", label="Pause" if player.playing else "Play")
        dpg.set_value(
            "time_text",
            f"t = {player.frame_time_s:7.3f} s   frame {player.frame + 1}/{player.n_frames}",
        )

    def on_play(self, *args) -> None:
        self.vm.player.play()
