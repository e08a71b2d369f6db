"""Dialogs: the open and export-folder file dialogs, the message pop-up and
the form asking for a camera file's missing scene facts."""

from __future__ import annotations

import os

import dearpygui.dearpygui as dpg

from .panel import Panel
from .theme import RED

__all__ = ["Dialogs"]


def _modal_window(tag: str, label: str, **options):
    """A modal window, hidden until shown, that cannot be collapsed."""
    return dpg.window(tag=tag, label=label, show=False, modal=True, no_collapse=True, **options)


class Dialogs(Panel):
    def build(self) -> None:
        s = self.app.safe
        with dpg.file_dialog(
            tag="open_dialog",
            show=False,
            width=760,
            height=460,
            modal=True,
            callback=s(self.app.recording_tab.on_open_chosen),
            default_path=self.vm.store.last_dir or os.getcwd(),
        ):
            dpg.add_file_extension(
                "Recordings and camera files{.h5,.hdf5,.seq,.csq,.jpg,.fff,.hcc}",
                color=(150, 255, 150, 255),
            )
            dpg.add_file_extension(
                "Recordings (*.h5 *.hdf5){.h5,.hdf5}", color=(150, 255, 150, 255)
            )
            dpg.add_file_extension(
                "FLIR (*.seq *.csq *.jpg *.fff){.seq,.csq,.jpg,.fff}", color=(150, 200, 255, 255)
            )
            dpg.add_file_extension("Telops (*.hcc){.hcc}", color=(150, 200, 255, 255))
            dpg.add_file_extension(".*")
        self._build_scene_form()
        dpg.add_file_dialog(
            tag="export_dialog",
            show=False,
            width=760,
            height=460,
            modal=True,
            directory_selector=True,
            callback=s(lambda sd, a, u: dpg.set_value("export_dir", a.get("file_path_name", ""))),
        )
        with _modal_window("popup", "qogi", width=560, pos=(300, 200)):
            dpg.add_text("", tag="popup_text", wrap=530)
            dpg.add_button(label="OK", width=80, callback=lambda: dpg.hide_item("popup"))

    def popup(self, title: str, text: str, level: str) -> None:
        dpg.configure_item("popup", label=title)
        dpg.set_value("popup_text", text)
        dpg.configure_item("popup_text", color=RED if level == "error" else (230, 230, 230))
        vw = dpg.get_viewport_client_width()
        dpg.configure_item("popup", pos=(max(0, vw // 2 - 280), 180))
        dpg.show_item("popup")

    # ----------------------------------------------------------------- scene facts
    def _build_scene_form(self) -> None:
        """The small form that asks for a camera file's missing scene facts."""
        from qogi.physics.presets import camera_preset_names

        from ..scene_form import FIELDS

        s, file = self.app.safe, self.vm.file
        with _modal_window(
            "scene_form",
            "Scene facts",
            width=620,
            pos=(260, 180),
            on_close=s(lambda *a: file.cancel_scene()),
        ):
            dpg.add_text("", tag="scene_title", wrap=590)
            for key, (label, unit) in FIELDS.items():
                with dpg.group(horizontal=True):
                    dpg.add_text(f"{label} [{unit}]" if key != "camera" else label)
                    if key == "camera":
                        dpg.add_combo(
                            list(camera_preset_names()),
                            tag="scene_camera_preset",
                            width=120,
                            callback=lambda sd, a, u: dpg.set_value("scene_f_camera", a),
                        )
                    dpg.add_input_text(tag=f"scene_f_{key}", width=220)
                dpg.add_text("", tag=f"scene_hint_{key}", color=(170, 170, 170, 255), wrap=590)
            dpg.add_text("", tag="scene_error", color=(255, 120, 120, 255), wrap=590)
            with dpg.group(horizontal=True):
                dpg.add_button(label="Open", width=90, callback=s(self.on_scene_submit))
                dpg.add_button(label="Cancel", width=90, callback=s(lambda *a: file.cancel_scene()))

    def on_scene_submit(self, *args) -> bool:
        from ..scene_form import FIELDS

        return self.vm.file.submit_scene({k: dpg.get_value(f"scene_f_{k}") for k in FIELDS})

    def refresh_scene_form(self) -> None:
        from ..scene_form import FIELDS

        req = self.vm.file.scene_request
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
