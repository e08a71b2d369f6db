"""The status bar: job progress and Cancel, the newest message, the message
list, the frame rate while playing."""

from __future__ import annotations

import time

import dearpygui.dearpygui as dpg

from .panel import Panel
from .theme import GREEN, GREY, RED, YELLOW

__all__ = ["StatusBar"]


class StatusBar(Panel):
    def __init__(self, app):
        super().__init__(app)
        self._n_messages = 0

    def build(self) -> None:
        s = self.app.safe
        dpg.add_separator()
        with dpg.group(horizontal=True, tag="status_bar"):
            dpg.add_progress_bar(tag="progress", width=420, overlay="idle")
            dpg.add_button(label="Cancel", tag="cancel_button", callback=s(self.on_cancel))
            dpg.bind_item_theme("cancel_button", self.app.themes["cancel"])
            dpg.add_button(label="Messages", callback=s(lambda *a: self.show_messages()))
            dpg.add_text("", tag="status_text")
            dpg.add_text("", tag="fps_text", color=GREY)

    def refresh_progress(self) -> None:
        work = self.vm.work
        p = work.progress()
        if p is None:
            dpg.configure_item("cancel_button", show=False)
            return
        running = p["state"] == "running"
        dpg.set_value("progress", p["fraction"])
        label = (
            f"{work.job.name}: {p['message']}"
            if running
            else f"{work.job.name} {p['state']} ({p['elapsed_s']:.1f} s)"
        )
        dpg.configure_item("progress", overlay=label[:60])
        dpg.configure_item("cancel_button", show=running)
        dpg.configure_item("run_button", enabled=not running)
        dpg.configure_item("demo_button", enabled=not running)

    def refresh_messages(self) -> bool:
        """Show the newest message (and new errors in a pop-up); True when
        there were new messages."""
        msgs = self.vm.log.messages
        if len(msgs) == self._n_messages:
            return False
        new = msgs[self._n_messages :]
        self._n_messages = len(msgs)
        last = msgs[-1]
        colour = {"error": RED, "warning": YELLOW}.get(last.level, GREEN)
        dpg.set_value("status_text", last.text[:200])
        dpg.configure_item("status_text", color=colour)
        errors = [m.text for m in new if m.level == "error"]
        if errors:
            self.app.dialogs.popup("Something needs attention", "\n\n".join(errors[-3:]), "error")
        return True

    def show_fps(self, fps: float, video_fps: float) -> None:
        dpg.set_value(
            "fps_text",
            f"playing: {fps:.0f} frames drawn/s, {video_fps:.0f} recording frames shown/s"
            if self.vm.player.playing
            else "",
        )

    def show_messages(self) -> None:
        """A window listing the last messages, newest first."""
        if dpg.does_item_exist("messages_window"):
            dpg.delete_item("messages_window")
        colours = {"error": RED, "warning": YELLOW, "info": (220, 220, 220)}
        with dpg.window(
            tag="messages_window", label="Messages", width=760, height=420, pos=(200, 120)
        ):
            for m in reversed(self.vm.log.messages[-60:]):
                stamp = time.strftime("%H:%M:%S", time.localtime(m.time_s))
                dpg.add_text(f"{stamp}  {m.text}", wrap=730, color=colours.get(m.level, GREY))

    def on_cancel(self, *args) -> None:
        self.vm.work.cancel()
