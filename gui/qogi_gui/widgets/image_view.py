"""The image: the frame as a texture, the result's overlay and vectors, the
drawn surfaces with their arrows, the region and the source; mouse clicks,
point dragging and keys; the read-out of the pixel under the cursor."""

from __future__ import annotations

import math

import dearpygui.dearpygui as dpg
import numpy as np

from .. import display, results
from ..surfaces import flow_arrow
from .display_tab import RANGE_CHOICES
from .panel import Panel
from .theme import rgb

__all__ = ["ImageView", "format_readout"]


class ImageView(Panel):
    def __init__(self, app):
        super().__init__(app)
        self._tex_shape = None
        self._overlay_items = []
        self._drag_points = []
        self._last_range = None
        self._unlock_axes = 0
        self._readout_text = ""

    # ----------------------------------------------------------------- build
    def build(self) -> None:
        themes = self.app.themes
        with dpg.group(horizontal=True):
            with dpg.plot(
                tag="img_plot",
                height=480,
                width=-90,
                equal_aspects=True,
                no_menus=True,
                no_box_select=True,
                no_mouse_pos=True,
                no_title=True,
            ):
                dpg.add_plot_axis(dpg.mvXAxis, tag="img_x", no_gridlines=True)
                dpg.add_plot_axis(dpg.mvYAxis, tag="img_y", invert=True, no_gridlines=True)
                dpg.add_line_series([], [], segments=True, tag="vectors", parent="img_y")
                dpg.bind_item_theme("vectors", themes["vectors"])
            dpg.bind_item_theme("img_plot", themes["image_plot"])
            dpg.add_colormap_scale(
                tag="img_scale",
                width=85,
                height=480,
                min_scale=0,
                max_scale=1,
                colormap="cmap_inferno",
                format="%.4g",
            )

    def build_readout(self) -> None:
        dpg.add_text("", tag="readout", color=(200, 220, 255))

    def build_handlers(self) -> None:
        s = self.app.safe
        with dpg.handler_registry():
            dpg.add_mouse_click_handler(
                button=dpg.mvMouseButton_Left, callback=s(lambda *a: self._mouse_click("left"))
            )
            dpg.add_mouse_click_handler(
                button=dpg.mvMouseButton_Right, callback=s(lambda *a: self._mouse_click("right"))
            )
            dpg.add_key_press_handler(callback=s(self._on_key))

    # ----------------------------------------------------------------- refresh
    def new_recording(self, rec) -> None:
        """Textures of the recording's size; the whole image in view."""
        shape = (rec.height, rec.width)
        if self._tex_shape != shape:
            for tag in ("frame_series", "overlay_series", "frame_tex", "overlay_tex"):
                if dpg.does_item_exist(tag):
                    dpg.delete_item(tag)
            # Texture row 0 is the image's top row; the y axis runs down (inverted),
            # so flip v to keep pixel (x, y) at plot (x, y).
            kw = dict(uv_min=(0.0, 1.0), uv_max=(1.0, 0.0), parent="img_y")
            for layer in ("frame", "overlay"):
                dpg.add_raw_texture(
                    rec.width,
                    rec.height,
                    np.zeros(rec.width * rec.height * 4, np.float32),
                    format=dpg.mvFormat_Float_rgba,
                    tag=f"{layer}_tex",
                    parent="textures",
                )
                dpg.add_image_series(
                    f"{layer}_tex",
                    (-0.5, -0.5),
                    (rec.width - 0.5, rec.height - 0.5),
                    tag=f"{layer}_series",
                    before="vectors",
                    **kw,
                )
            self._tex_shape = shape

    def fit_image(self) -> None:
        rec = self.vm.recording
        if rec is None:
            return
        dpg.set_axis_limits("img_x", -0.5, rec.width - 0.5)
        dpg.set_axis_limits("img_y", -0.5, rec.height - 0.5)
        self._unlock_axes = 2

    def upload_frame(self) -> None:
        """The shown frame, overlay and vectors into the plot."""
        vm = self.vm
        rgba = vm.video.render()
        dpg.set_value("frame_tex", rgba)
        over = vm.overlay.render()
        if over is not None:
            dpg.set_value("overlay_tex", over)
        dpg.configure_item("overlay_series", show=over is not None)
        tails, heads, scale = vm.overlay.vectors(spacing=max(8, vm.recording.width // 28))
        xs, ys = results.arrow_segments(tails, heads, min_head=1.5)
        dpg.set_value("vectors", [list(xs), list(ys)])
        self.app.display_tab.show_overlay_note(over is not None, scale)
        lo, hi = vm.video.last_range
        if (lo, hi) != self._last_range:
            self._last_range = (lo, hi)
            dpg.configure_item("img_scale", min_scale=lo, max_scale=hi)

    def refresh_overlays(self) -> None:
        """Surfaces, their arrows and names, the region, the drawing in progress."""
        editor = self.vm.editor
        for item in self._overlay_items + self._drag_points:
            if dpg.does_item_exist(item):
                dpg.delete_item(item)
        self._overlay_items, self._drag_points = [], []
        rec = self.vm.recording
        if rec is None:
            return
        arrow_len = max(6.0, 0.05 * max(rec.width, rec.height))
        themes = self.app.themes

        def series(xs, ys, theme, segments=False, scatter=False):
            if scatter:
                t = dpg.add_scatter_series(list(xs), list(ys), parent="img_y")
            else:
                t = dpg.add_line_series(list(xs), list(ys), parent="img_y", segments=segments)
            dpg.bind_item_theme(t, themes[theme])
            self._overlay_items.append(t)
            return t

        for i, srf in enumerate(editor.surfaces):
            xs, ys = zip(*srf.points)
            c = srf.colour
            series(xs, ys, ("selected", c) if i == editor.selected else ("line", c))
            series(xs, ys, ("marker", c), scatter=True)
            arrow = flow_arrow(srf.points, arrow_len)
            if arrow is not None:
                ax, ay = results.arrow_segments(np.array([arrow[0]]), np.array([arrow[1]]))
                series(ax, ay, ("line", c), segments=True)
            x0, y0 = srf.points[0]
            self._overlay_items.append(
                dpg.add_plot_annotation(
                    label=srf.name,
                    default_value=(x0, y0),
                    offset=(-12, -10),
                    color=rgb(c, 200),
                    parent="img_plot",
                )
            )
            if editor.mode == "edit":
                for j, (x, y) in enumerate(srf.points):
                    self._drag_points.append(
                        dpg.add_drag_point(
                            default_value=(x, y),
                            color=rgb(c),
                            parent="img_plot",
                            user_data=(i, j),
                            show_label=False,
                            callback=self.app.safe(self._on_drag),
                        )
                    )
        if editor.drawing is not None and editor.drawing.points:
            xs, ys = zip(*editor.drawing.points)
            series(xs, ys, "drawing")
        if editor.region is not None:
            r = editor.region
            x0, x1, y0, y1 = r.x0 - 0.5, r.x1 - 0.5, r.y0 - 0.5, r.y1 - 0.5
            series([x0, x1, x1, x0, x0], [y0, y0, y1, y1, y0], "region")
            self._overlay_items.append(
                dpg.add_plot_annotation(
                    label="background",
                    default_value=(x0, y0),
                    offset=(30, -8),
                    color=(255, 255, 255, 160),
                    parent="img_plot",
                )
            )
        if editor.region_corner is not None:
            series([editor.region_corner[0]], [editor.region_corner[1]], "drawing", scatter=True)
        src = self.vm.form.source_point()
        if src is not None:
            sx, sy = src
            series([sx - 3, sx + 3, sx, sx], [sy, sy, sy - 3, sy + 3], "region", segments=True)
        # Panning with the left button would fight with clicking points in.
        pan = dpg.mvMouseButton_Left if editor.mode == "view" else dpg.mvMouseButton_Middle
        dpg.configure_item("img_plot", pan_button=pan)

    def refresh_readout(self) -> None:
        vm = self.vm
        if self._unlock_axes:
            self._unlock_axes -= 1
            if self._unlock_axes == 0:  # set_axis_limits pins the axes; free them for zoom
                dpg.set_axis_limits_auto("img_x")
                dpg.set_axis_limits_auto("img_y")
        if vm.recording is None:
            return
        r = None
        if dpg.is_item_hovered("img_plot"):
            x, y = dpg.get_plot_mouse_pos()
            r = vm.video.readout(x, y)
        if r is not None:
            text = format_readout(r)
        else:
            d = vm.video.display
            lo, hi = vm.video.last_range
            rng = {v: k for k, v in RANGE_CHOICES.items()}[d.range_mode]
            text = (
                f"colours: channel {d.channel} {display.QUANTITY_LABELS[d.quantity]} "
                f"{lo:.5g} .. {hi:.5g}, {rng}; point at the image for pixel values"
            )
        if text != self._readout_text:
            self._readout_text = text
            dpg.set_value("readout", text)

    # ----------------------------------------------------------------- input
    def image_click(self, x: float, y: float, button: str = "left") -> bool:
        """A click on the image at pixel coordinates (what the mouse handler calls)."""
        tol = 6.0 * self._image_px_per_screen_px()
        return self.vm.editor.click(x, y, button, tolerance_px=tol)

    def _image_px_per_screen_px(self) -> float:
        try:
            lo, hi = dpg.get_axis_limits("img_x")
            w = dpg.get_item_rect_size("img_plot")[0]
            return max(1e-3, (hi - lo) / max(1, w - 40))
        except Exception:  # noqa: BLE001 - before the first frame the plot has no size yet
            return 1.0

    def _mouse_click(self, button: str) -> None:
        mode = self.vm.editor.mode
        if self.vm.recording is None or not dpg.is_item_hovered("img_plot"):
            return
        if mode == "view" and button == "left":
            return  # look mode: clicks pan; selection is in edit mode
        if mode == "edit" and self._over_drag_point():
            return
        x, y = dpg.get_plot_mouse_pos()
        self.image_click(x, y, button)

    def _over_drag_point(self) -> bool:
        x, y = dpg.get_plot_mouse_pos()
        tol = 8.0 * self._image_px_per_screen_px()
        return any(math.dist((x, y), p) <= tol for s in self.vm.editor.surfaces for p in s.points)

    def _on_drag(self, sender, app_data, user_data) -> None:
        i, j = user_data
        x, y = dpg.get_value(sender)[:2]
        self.vm.editor.move_vertex(i, j, x, y)

    def _on_key(self, sender, key, user_data) -> None:
        if not dpg.is_item_hovered("img_plot"):
            return  # keys act on the image only, never while typing in a field
        player, editor = self.vm.player, self.vm.editor
        if key == dpg.mvKey_Spacebar:
            player.play()
        elif key == dpg.mvKey_Right:
            player.step(1)
        elif key == dpg.mvKey_Left:
            player.step(-1)
        elif key == dpg.mvKey_Return:
            editor.finish_drawing()
        elif key == dpg.mvKey_Escape:
            editor.cancel_drawing()
            editor.set_mode("view")
        elif key == dpg.mvKey_Back:
            editor.undo_point()
        elif key == dpg.mvKey_Delete and editor.selected is not None:
            editor.delete_surface(editor.selected)


def format_readout(r: dict) -> str:
    """One line describing the pixel under the cursor."""
    parts = [f"pixel ({r['x']}, {r['y']})"]
    for ch in r["channels"]:
        parts.append(f"{ch['name']}: {ch['radiance']:.5g} W/(m2 sr), {ch['temperature_K']:.2f} K")
    for sp, v in r.get("column_density_kg_m2", {}).items():
        parts.append(f"{sp} {v * 1e3:.3g} g/m2")
    if "velocity_m_s" in r:
        u, v = r["velocity_m_s"]
        parts.append(f"velocity ({u:.2f}, {-v:.2f}) m/s (right, up)")
    if "status" in r:
        parts.append(f"status {r['status']}")
    return " | ".join(parts)
