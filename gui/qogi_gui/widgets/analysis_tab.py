"""The Analysis tab: the form, each field's unit, range and message, and Run."""

from __future__ import annotations

import dearpygui.dearpygui as dpg

from ..settings import (
    AVERAGING,
    BACKGROUNDS,
    FIELDS,
    GAS_TEMPERATURE_MODES,
    LINE_SHAPE_BROADENINGS,
    LINE_SHAPE_WINGS,
    velocity_choices,
)
from .panel import Panel
from .theme import GREY, LEFT_WIDTH, RED

__all__ = ["AnalysisTab"]

#: Text fields pushed from the form into their widgets ``f_<key>``.
TEXT_FIELDS = (
    "gas_temperature_K",
    "wind_speed_m_s",
    "exit_velocity_m_s",
    "background_percentile",
    "distance_m",
    "ambient_temperature_K",
    "pressure_Pa",
    "sigma_m",
    "exit_temperature_K",
    "line_shape_wing_cm1",
    "frame_start",
    "frame_stop",
    "num_threads",
)
#: Choice fields: form field -> widget tag.
CHOICE_FIELDS = {
    "gas_temperature_mode": "f_gas_mode",
    "velocity": "f_velocity",
    "averaging": "f_averaging",
    "background": "f_background",
    "use_source": "f_use_source",
    "source_x": "f_source_x",
    "source_y": "f_source_y",
    "keep_maps": "f_keep_maps",
    "line_shape_wing": "f_line_shape_wing",
    "line_shape_broadening": "f_line_shape_broadening",
}


class AnalysisTab(Panel):
    def build(self) -> None:
        s = self.app.safe
        w = 130
        msgw = LEFT_WIDTH - 20

        def hint(key):
            dpg.add_text("", tag=f"msg_{key}", wrap=msgw, color=GREY, indent=12)

        def text_field(key, label, unit=""):
            with dpg.group(horizontal=True, tag=f"row_{key}"):
                dpg.add_input_text(
                    label=f"{label}{' [' + unit + ']' if unit else ''}",
                    tag=f"f_{key}",
                    width=w,
                    callback=s(lambda sd, a, u: self.on_field(u, a)),
                    user_data=key,
                )
            hint(key)

        def choice(key, tag, label, items):
            dpg.add_combo(
                list(items),
                label=label,
                tag=tag,
                width=w,
                default_value=items[0],
                callback=s(lambda sd, a, u: self.on_field(key, a)),
            )

        dpg.add_text("Species")
        dpg.add_group(tag="species_group", horizontal=True)
        hint("species")
        choice("gas_temperature_mode", "f_gas_mode", "gas temperature", GAS_TEMPERATURE_MODES)
        text_field("gas_temperature_K", "given gas temperature", "K")
        text_field("exit_temperature_K", "exit temperature", "K")
        choice("velocity", "f_velocity", "velocity source", velocity_choices())
        hint("velocity")
        text_field("wind_speed_m_s", "wind speed", "m/s")
        text_field("exit_velocity_m_s", "exit velocity", "m/s")
        choice("averaging", "f_averaging", "averaging order", AVERAGING)
        hint("averaging")
        choice("background", "f_background", "background", BACKGROUNDS)
        hint("background")
        text_field("background_percentile", "background percentile", "%")
        dpg.add_separator()
        dpg.add_text("Line shape of the cross-sections")
        choice("line_shape_wing", "f_line_shape_wing", "wing rule", LINE_SHAPE_WINGS)
        text_field("line_shape_wing_cm1", "wing half-width", "cm-1")
        choice(
            "line_shape_broadening", "f_line_shape_broadening", "broadening", LINE_SHAPE_BROADENINGS
        )
        hint("line_shape")
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
            dpg.add_checkbox(
                label="source at",
                tag="f_use_source",
                callback=s(lambda sd, a, u: self.on_field("use_source", a)),
            )
            dpg.add_input_text(
                tag="f_source_x",
                width=60,
                hint="x",
                callback=s(lambda sd, a, u: self.on_field("source_x", a)),
            )
            dpg.add_input_text(
                tag="f_source_y",
                width=60,
                hint="y",
                callback=s(lambda sd, a, u: self.on_field("source_y", a)),
            )
            dpg.add_button(label="pick", callback=s(lambda *a: self.app.set_mode("source")))
        hint("source")
        text_field("num_threads", "threads")
        dpg.add_checkbox(
            label="keep per-pixel maps (overlay, vectors)",
            tag="f_keep_maps",
            default_value=True,
            callback=s(lambda sd, a, u: self.on_field("keep_maps", a)),
        )
        dpg.add_spacer(height=6)
        with dpg.group(horizontal=True):
            dpg.add_button(
                label="Run quantification",
                tag="run_button",
                width=180,
                height=30,
                callback=s(self.on_run),
            )
            dpg.bind_item_theme("run_button", self.app.themes["run"])

    def refresh(self) -> None:
        """Push the form's values into the widgets (after open, or a pick on the image)."""
        form = self.vm.form
        st = form.settings
        dpg.delete_item("species_group", children_only=True)
        for name, on in st.species.items():
            dpg.add_checkbox(
                label=name,
                default_value=on,
                parent="species_group",
                user_data=name,
                callback=self.app.safe(self._on_species),
            )
        for key in TEXT_FIELDS:
            dpg.set_value(f"f_{key}", str(getattr(st, key)))
        for key, tag in CHOICE_FIELDS.items():
            dpg.set_value(tag, getattr(st, key))
        if self.vm.recording is not None:
            form.validate_settings()
        self.refresh_messages()

    def refresh_messages(self) -> None:
        """Each field's message: its problem in red, else what it accepts."""
        vm = self.vm
        st = vm.form.settings
        hints = st.hints(vm.recording)
        errs = vm.form.field_errors
        for key in FIELDS:
            tag = f"msg_{key}"
            if not dpg.does_item_exist(tag):
                continue
            e = errs.get(key, "")
            dpg.set_value(tag, e if e else hints.get(key, ""))
            dpg.configure_item(tag, color=RED if e else GREY)
        show = {
            "gas_temperature_K": st.gas_temperature_mode == "given",
            "wind_speed_m_s": st.velocity == "wind",
            "exit_velocity_m_s": st.velocity == "exit",
            "background_percentile": st.background in ("percentile", "drifting"),
            "line_shape_wing_cm1": st.line_shape_wing == "fixed",
        }
        for key, on in show.items():
            dpg.configure_item(f"row_{key}", show=on)
            dpg.configure_item(f"msg_{key}", show=on)

    def on_field(self, key: str, value) -> None:
        self.vm.form.update_settings(**{key: value})
        self.refresh_messages()

    def _on_species(self, sender, value, name) -> None:
        species = dict(self.vm.form.settings.species)
        species[name] = bool(value)
        self.on_field("species", species)

    def on_run(self, *args) -> None:
        if self.vm.run.start_run():
            self.app.select_tab("results")
