"""The Display tab: how the video is drawn, and the result on it."""

from __future__ import annotations

import dearpygui.dearpygui as dpg

from .. import display
from .panel import Panel
from .theme import GREY, LEFT_WIDTH

__all__ = ["DisplayTab", "QUANTITY_CHOICES", "RANGE_CHOICES"]

QUANTITY_CHOICES = {
    "band radiance [W/(m2 sr)]": "radiance",
    "radiometric temperature [K]": "radiometric_temperature",
}
RANGE_CHOICES = {
    "auto (whole recording)": "recording",
    "auto (this frame)": "frame",
    "fixed": "fixed",
}


class DisplayTab(Panel):
    def build(self) -> None:
        s, video = self.app.safe, self.vm.video
        dpg.add_combo([], label="channel", tag="d_channel", width=260, callback=s(self._on_channel))
        dpg.add_radio_button(
            list(QUANTITY_CHOICES),
            tag="d_quantity",
            callback=s(lambda sd, a, u: video.set_display(quantity=QUANTITY_CHOICES[a])),
        )
        self._choice(display.COLORMAPS, "colour map", "d_cmap", 160, "colormap")
        dpg.add_radio_button(
            list(RANGE_CHOICES),
            tag="d_range",
            horizontal=False,
            callback=s(lambda sd, a, u: video.set_display(range_mode=RANGE_CHOICES[a])),
        )
        with dpg.group(horizontal=True):
            for end in ("min", "max"):
                dpg.add_input_double(
                    label=end,
                    tag=f"d_{end}",
                    width=120,
                    format="%.6g",
                    on_enter=True,
                    callback=s(self._on_fixed_range),
                )
        dpg.add_button(
            label="Fix the range shown now", tag="d_fix_now", callback=s(self._on_fix_now)
        )
        dpg.add_text(
            "Zoom with the mouse wheel, pan by dragging (in look mode), double-click to fit.",
            wrap=LEFT_WIDTH - 20,
            color=GREY,
        )
        dpg.add_separator()
        dpg.add_text("Results on the video")
        dpg.add_checkbox(
            label="overlay",
            tag="d_overlay",
            default_value=True,
            callback=s(lambda sd, a, u: video.set_display(show_overlay=a)),
        )
        self._choice(display.OVERLAY_KINDS, "shows", "d_overlay_kind", 200, "overlay_kind")
        dpg.add_combo(
            [],
            label="species",
            tag="d_overlay_species",
            width=120,
            callback=s(lambda sd, a, u: video.set_display(overlay_species=a)),
        )
        self._choice(
            display.OVERLAY_COLORMAPS, "overlay colours", "d_overlay_cmap", 120, "overlay_colormap"
        )
        dpg.add_checkbox(
            label="velocity vectors",
            tag="d_vectors",
            default_value=True,
            callback=s(lambda sd, a, u: video.set_display(show_vectors=a)),
        )
        with dpg.group(horizontal=True):
            dpg.add_button(
                label="< frame with maps",
                tag="d_prev_maps",
                callback=s(lambda *a: self.vm.overlay.seek_map_frame(-1)),
            )
            dpg.add_button(
                label="frame with maps >",
                tag="d_next_maps",
                callback=s(lambda *a: self.vm.overlay.seek_map_frame(1)),
            )
        dpg.add_text("", tag="d_overlay_note", wrap=LEFT_WIDTH - 20, color=GREY)

    def new_recording(self, rec) -> None:
        dpg.configure_item(
            "d_channel", items=[f"{k}: {ch.name}" for k, ch in enumerate(rec.channels)]
        )
        dpg.set_value("d_channel", f"0: {rec.channels[0].name}")

    def new_result(self) -> None:
        species = self.vm.run.result_species()
        dpg.configure_item("d_overlay_species", items=species)
        if species:
            dpg.set_value("d_overlay_species", self.vm.overlay.species())

    def refresh(self) -> None:
        """Push the display settings into the widgets."""
        d, rec = self.vm.video.display, self.vm.recording
        if rec is not None:
            dpg.set_value("d_channel", f"{d.channel}: {rec.channels[d.channel].name}")
        dpg.set_value("d_quantity", {v: k for k, v in QUANTITY_CHOICES.items()}[d.quantity])
        dpg.set_value("d_cmap", d.colormap)
        dpg.set_value("d_range", {v: k for k, v in RANGE_CHOICES.items()}[d.range_mode])
        dpg.set_value("d_min", d.fixed_min)
        dpg.set_value("d_max", d.fixed_max)
        dpg.set_value("d_overlay", d.show_overlay)
        dpg.set_value("d_overlay_kind", d.overlay_kind)
        dpg.set_value("d_vectors", d.show_vectors)
        dpg.configure_item("img_scale", colormap=f"cmap_{d.colormap}")

    def show_overlay_note(self, shown: bool, scale: float) -> None:
        """What the overlay and the vectors on the shown frame mean (or why
        there are none)."""
        vm = self.vm
        run, note = vm.run, ""
        if run.result is not None and vm.video.display.overlay_kind == display.OVERLAY_KINDS[1]:
            got = vm.overlay.detectability()
            note = (
                f"overlay: {vm.overlay.species()} minimum-detectable column "
                f"{got[1] * 1e3:.3g} .. {got[2] * 1e3:.3g} g/m2 (a pixel must hold this column "
                "to be seen in 95 % of frames; clear: no contrast)"
                if got is not None and shown
                else "this result has no minimum-detectable column map (truth columns)"
            )
        elif run.result is not None and shown:
            note = (
                f"overlay: {vm.overlay.species()} column density 0 .. "
                f"{vm.overlay.vmax() * 1e3:.3g} g/m2"
            )
            if scale > 0:
                note += (
                    f"; vectors: 1 px/frame = {vm.video.px_per_frame_to_m_s():.3g} m/s, "
                    f"drawn {scale:.2g} px long"
                )
        elif run.result is not None and not run.result_has_maps:
            note = "run with 'keep per-pixel maps' to see the overlay and vectors"
        if run.result is not None and run.result_has_maps:
            kept = vm.overlay.map_frames()
            n = vm.player.n_frames
            if len(kept) < n:
                note += (
                    ("; " if note else "") + f"maps kept for {len(kept)} of {n} "
                    "frames: step between them with the buttons above"
                )
        dpg.set_value("d_overlay_note", note)

    def _choice(self, items, label: str, tag: str, width: int, field: str) -> None:
        """A list of choices that sets display setting ``field`` (the first is the default)."""
        video = self.vm.video
        dpg.add_combo(
            list(items),
            label=label,
            tag=tag,
            width=width,
            default_value=items[0],
            callback=self.app.safe(lambda sd, a, u: video.set_display(**{field: a})),
        )

    def _on_channel(self, sender, value, user_data) -> None:
        self.vm.video.set_display(channel=int(str(value).split(":", 1)[0]))

    def _on_fixed_range(self, *args) -> None:
        self.vm.video.set_display(
            fixed_min=dpg.get_value("d_min"), fixed_max=dpg.get_value("d_max"), range_mode="fixed"
        )

    def _on_fix_now(self, *args) -> None:
        lo, hi = self.vm.video.last_range
        self.vm.video.set_display(fixed_min=lo, fixed_max=hi, range_mode="fixed")
