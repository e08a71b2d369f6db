"""The Surfaces tab: what a click on the image does, the surface list, the
background region."""

from __future__ import annotations

import dearpygui.dearpygui as dpg

from ..panels.drawing import MODES
from .panel import Panel
from .theme import GREY, LEFT_WIDTH, rgb

__all__ = ["SurfacesTab", "MODE_LABELS"]

MODE_LABELS = {
    "view": "look (pan, zoom, read-out)",
    "line": "draw a line (2 clicks)",
    "polyline": "draw a polyline (right-click / Enter ends)",
    "region": "pick background region (2 corners)",
    "source": "pick the source",
    "edit": "edit (drag points)",
}


class SurfacesTab(Panel):
    def build(self) -> None:
        s, editor = self.app.safe, self.vm.editor
        dpg.add_text("What a click on the image does:")
        dpg.add_radio_button(
            [MODE_LABELS[m] for m in MODES],
            tag="mode",
            default_value=MODE_LABELS["view"],
            callback=s(lambda sd, a, u: editor.set_mode({v: k for k, v in MODE_LABELS.items()}[a])),
        )
        with dpg.group(horizontal=True):
            dpg.add_button(label="Finish surface", callback=s(lambda *a: editor.finish_drawing()))
            dpg.add_button(label="Undo point", callback=s(lambda *a: editor.undo_point()))
            dpg.add_button(label="Cancel drawing", callback=s(lambda *a: editor.cancel_drawing()))
        with dpg.group(horizontal=True):
            dpg.add_button(
                label="Automatic surfaces at",
                tag="auto_surfaces_button",
                callback=s(lambda *a: self.on_auto_surfaces()),
            )
            dpg.add_input_text(tag="auto_distances", default_value="30, 60, 90", width=110)
            dpg.add_text("px from the source")
        dpg.add_text(
            "Flux counts positive in the direction of each surface's arrow: the "
            "left-hand side walking from its first point to its last. Reverse a "
            "surface to flip it, or set the source (Analysis) to orient them all "
            "away from it.",
            wrap=LEFT_WIDTH - 20,
            color=GREY,
        )
        dpg.add_separator()
        dpg.add_text("Control surfaces")
        dpg.add_group(tag="surface_list")
        dpg.add_separator()
        dpg.add_text("Background region: none", tag="region_text")
        with dpg.group(horizontal=True):
            dpg.add_button(label="Pick region", callback=s(lambda *a: self.app.set_mode("region")))
            dpg.add_button(label="Clear region", callback=s(lambda *a: editor.set_region(None)))

    def on_auto_surfaces(self) -> None:
        text = dpg.get_value("auto_distances") or ""
        try:
            dists = [float(v) for v in text.replace(";", ",").split(",") if v.strip()]
        except ValueError:
            self.vm.log.error(
                f"distances: give numbers of pixels separated by commas; got {text!r}"
            )
            return
        self.vm.editor.auto_surfaces(dists)

    def refresh(self) -> None:
        """The surface list, the mode and the region's description."""
        editor, s = self.vm.editor, self.app.safe
        dpg.delete_item("surface_list", children_only=True)
        if not editor.surfaces:
            dpg.add_text(
                "none yet: choose 'draw a line' and click twice across the plume",
                parent="surface_list",
                color=GREY,
                wrap=LEFT_WIDTH - 20,
            )
        for i, srf in enumerate(editor.surfaces):
            with dpg.group(horizontal=True, parent="surface_list"):
                dpg.add_input_text(
                    default_value=srf.name,
                    width=70,
                    on_enter=True,
                    user_data=i,
                    callback=s(lambda sd, a, u: editor.rename_surface(u, a)),
                )
                pts = " > ".join(f"({x:.0f},{y:.0f})" for x, y in srf.points)
                dpg.add_text(pts if len(pts) < 30 else pts[:27] + "...", color=rgb(srf.colour))
                dpg.add_button(
                    label="reverse",
                    user_data=i,
                    callback=s(lambda sd, a, u: editor.reverse_surface(u)),
                )
                dpg.add_button(
                    label="delete",
                    user_data=i,
                    callback=s(lambda sd, a, u: editor.delete_surface(u)),
                )
        dpg.set_value("mode", MODE_LABELS[editor.mode])
        r = editor.region
        dpg.set_value(
            "region_text",
            "Background region: none"
            if r is None
            else f"Background region: x {r.x0}..{r.x1 - 1}, y {r.y0}..{r.y1 - 1} ({r.n_pixels} px)",
        )
