"""The Recording tab: open a file or the demo, recent files, what is open."""

from __future__ import annotations

import os

import dearpygui.dearpygui as dpg

from .panel import Panel
from .theme import GREY, LEFT_WIDTH

__all__ = ["RecordingTab"]


class RecordingTab(Panel):
    def build(self) -> None:
        s = self.app.safe
        with dpg.group(horizontal=True):
            dpg.add_button(label="Open recording...", callback=s(self.on_open_dialog))
            dpg.add_button(label="Load demo scene", tag="demo_button", callback=s(self.on_demo))
        dpg.add_spacer(height=4)
        with dpg.table(
            tag="meta_table",
            header_row=False,
            borders_innerH=True,
            policy=dpg.mvTable_SizingStretchProp,
        ):
            dpg.add_table_column(init_width_or_weight=0.36)
            dpg.add_table_column(init_width_or_weight=0.64)
        dpg.add_text(
            "Open a recording (.h5) or load the demo scene.",
            tag="meta_hint",
            wrap=LEFT_WIDTH - 20,
            color=GREY,
        )
        dpg.add_spacer(height=8)
        dpg.add_text("Recent recordings")
        dpg.add_group(tag="recent_list")

    def refresh(self) -> None:
        """The open recording's description and the recent files."""
        vm = self.vm
        dpg.delete_item("meta_table", children_only=True, slot=1)
        for label, value in vm.file.metadata_rows():
            with dpg.table_row(parent="meta_table"):
                dpg.add_text(label, color=GREY)
                dpg.add_text(value, wrap=260)
        dpg.configure_item("meta_hint", show=vm.recording is None)
        self.refresh_recent()
        if vm.recording is not None:
            dpg.set_viewport_title(f"qogi viewer - {os.path.basename(vm.file.path or '')}")

    def refresh_recent(self) -> None:
        """The recent files, in the File menu and on the tab."""
        dpg.delete_item("recent_menu", children_only=True)
        dpg.delete_item("recent_list", children_only=True)
        recent = self.vm.store.recent
        if not recent:
            dpg.add_menu_item(label="(none yet)", parent="recent_menu", enabled=False)
            dpg.add_text("(none yet)", parent="recent_list", color=GREY)
        open_it = self.app.safe(lambda sd, a, u: self.vm.file.open(u, background=True))
        for p in recent:
            dpg.add_menu_item(label=p, parent="recent_menu", user_data=p, callback=open_it)
            name = os.path.basename(p)
            dpg.add_button(
                label=name if len(name) < 52 else "..." + name[-49:],
                parent="recent_list",
                user_data=p,
                callback=open_it,
            )
            with dpg.tooltip(dpg.last_item()):
                dpg.add_text(p)

    def on_open_dialog(self, *args) -> None:
        dpg.show_item("open_dialog")

    def on_open_chosen(self, sender, app_data, user_data) -> None:
        sel = app_data.get("selections") or {}
        path = next(iter(sel.values()), None) or app_data.get("file_path_name", "")
        self.vm.file.open(path, background=True)

    def on_demo(self, *args) -> None:
        self.vm.file.open_demo()
