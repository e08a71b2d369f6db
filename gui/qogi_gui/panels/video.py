"""The video: how the shown frame is drawn (channel, quantity, colours,
range) and what the pixel under the cursor holds."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Dict, Optional, Tuple

import numpy as np

from .. import display

__all__ = ["Video", "DisplayState", "RANGE_MODES"]

RANGE_MODES = ("recording", "frame", "fixed")


@dataclass
class DisplayState:
    """How the video is drawn."""

    channel: int = 0
    quantity: str = "radiance"  # or "radiometric_temperature"
    colormap: str = display.COLORMAPS[0]
    range_mode: str = "recording"  # "recording" (auto, fixed over the video), "frame", "fixed"
    fixed_min: float = 0.0
    fixed_max: float = 1.0
    show_overlay: bool = True  # column density over the video (when a result has maps)
    overlay_kind: str = display.OVERLAY_KINDS[0]
    overlay_species: str = ""
    overlay_colormap: str = display.OVERLAY_COLORMAPS[0]
    show_vectors: bool = True  # velocity vectors (when a result has maps)


class Video:
    """The Display tab and the image: the shown frame as RGBA, and the read-out."""

    def __init__(self, vm):
        self.vm = vm
        self.display = DisplayState()
        self.last_range: Tuple[float, float] = (0.0, 1.0)
        self._frame_cache: Tuple[Optional[int], Optional[np.ndarray]] = (None, None)
        self._range_cache: Dict[tuple, Tuple[float, float]] = {}
        self._rgba: Optional[np.ndarray] = None
        self._scratch: Optional[np.ndarray] = None

    def reset(self, rec) -> None:
        self.display.channel = 0
        self.display.quantity = rec.quantity
        self._frame_cache = (None, None)
        self._range_cache.clear()
        h, w = rec.height, rec.width
        self._rgba = np.zeros((h, w, 4), np.float32)
        self._scratch = np.empty((h, w), np.float32)
        self.display.fixed_min, self.display.fixed_max = self.auto_range()

    # ----------------------------------------------------------------- settings
    def set_display(self, **changes) -> bool:
        """Change display settings (fields of :class:`DisplayState`), checked."""
        d, rec, error = self.display, self.vm.recording, self.vm.log.error
        for k, v in changes.items():
            if not hasattr(d, k):
                return error(f"unknown display setting {k!r}")
            if k == "channel" and rec is not None and not 0 <= int(v) < rec.n_channels:
                return error(f"channel must be 0..{rec.n_channels - 1}; got {v}")
            if k == "quantity" and v not in display.QUANTITY_LABELS:
                return error(f"quantity must be one of {', '.join(display.QUANTITY_LABELS)}")
            if k == "colormap" and v not in display.COLORMAPS:
                return error(f"colour map must be one of {', '.join(display.COLORMAPS)}")
            if k == "overlay_kind" and v not in display.OVERLAY_KINDS:
                return error(f"overlay must be one of {', '.join(display.OVERLAY_KINDS)}")
            if k == "overlay_colormap" and v not in display.OVERLAY_COLORMAPS:
                return error(
                    f"overlay colour map must be one of {', '.join(display.OVERLAY_COLORMAPS)}"
                )
            if k == "range_mode" and v not in RANGE_MODES:
                return error(f"range must be one of {', '.join(RANGE_MODES)}")
        fixed = {k: changes[k] for k in ("fixed_min", "fixed_max") if k in changes}
        if fixed:
            try:
                lo = float(fixed.get("fixed_min", d.fixed_min))
                hi = float(fixed.get("fixed_max", d.fixed_max))
            except (TypeError, ValueError):
                return error("the fixed range needs two numbers")
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                return error(f"the fixed range needs min < max; got {lo:g} .. {hi:g}")
            changes["fixed_min"], changes["fixed_max"] = lo, hi
        if "channel" in changes:
            changes["channel"] = int(changes["channel"])
        for k, v in changes.items():
            setattr(d, k, v)
        if (
            ("channel" in changes or "quantity" in changes)
            and rec is not None
            and "fixed_min" not in changes
        ):
            # A fixed range in other units would be meaningless: restart it from auto.
            d.fixed_min, d.fixed_max = self.auto_range()
        self.vm.rev["display"] += 1
        return True

    @property
    def unit(self) -> str:
        return "W/(m2 sr)" if self.display.quantity == "radiance" else "K"

    # ----------------------------------------------------------------- the frame
    def current_frame(self) -> np.ndarray:
        """All channels of the shown frame, stored quantity, (C, H, W) float32 (cached)."""
        frame = self.vm.player.frame
        i, a = self._frame_cache
        if i != frame or a is None:
            a = self.vm.recording.frames(frame, frame + 1)[0]
            self._frame_cache = (frame, a)
        return a

    def channel_image(self) -> np.ndarray:
        """The shown channel of the shown frame in the displayed quantity, (H, W)."""
        rec = self.vm.recording
        a = self.current_frame()[self.display.channel]
        q = self.display.quantity
        if q == rec.quantity:
            return a
        from qogi.radiometry import band_table

        table = band_table(rec.channels[self.display.channel])
        return table.radiance(a) if q == "radiance" else table.temperature(a)

    def auto_range(self) -> Tuple[float, float]:
        """Robust range of the shown channel and quantity over the recording (cached)."""
        key = (self.display.channel, self.display.quantity)
        if key not in self._range_cache:
            self._range_cache[key] = display.recording_range(self.vm.recording, *key)
        return self._range_cache[key]

    def display_range(self, image: Optional[np.ndarray] = None) -> Tuple[float, float]:
        d = self.display
        if d.range_mode == "fixed":
            return d.fixed_min, d.fixed_max
        if d.range_mode == "frame":
            return display.robust_range(self.channel_image() if image is None else image)
        return self.auto_range()

    def render(self) -> Optional[np.ndarray]:
        """The shown frame as RGBA float32 (H, W, 4) in a reused buffer (None
        without a recording). Also sets :attr:`last_range`."""
        if self.vm.recording is None:
            return None
        img = self.channel_image()
        lo, hi = self.display_range(img)
        self.last_range = (lo, hi)
        return display.colorize(
            img,
            lo,
            hi,
            display.colormap_lut(self.display.colormap),
            out=self._rgba,
            scratch=self._scratch,
        )

    # ----------------------------------------------------------------- read-out
    def px_per_frame_to_m_s(self) -> float:
        """Speed [m/s] of 1 px/frame at the scene distance (pixel size x frame rate)."""
        rec = self.vm.recording
        if rec is None:
            return math.nan
        return (
            float(rec.scene.distance_m)
            * float(rec.camera.ifov_rad)
            * float(rec.camera.frame_rate_hz)
        )

    def readout(self, x: float, y: float) -> Optional[dict]:
        """What is under the cursor at pixel coordinates (x, y): per channel the
        band radiance [W/(m2 sr)] and radiometric temperature [K]; with a
        result, column density and velocity. None outside the image."""
        rec = self.vm.recording
        if rec is None or not (math.isfinite(x) and math.isfinite(y)):
            return None
        ix, iy = int(math.floor(x + 0.5)), int(math.floor(y + 0.5))
        if not (0 <= ix < rec.width and 0 <= iy < rec.height):
            return None
        from qogi.radiometry import band_table

        frame = self.current_frame()
        player = self.vm.player
        out = {
            "x": ix,
            "y": iy,
            "frame": player.frame,
            "time_s": player.frame_time_s,
            "channels": [],
        }
        for k, ch in enumerate(rec.channels):
            v = np.float64(frame[k, iy, ix])
            if not np.isfinite(v):
                out["channels"].append(
                    {"name": ch.name, "radiance": math.nan, "temperature_K": math.nan}
                )
                continue
            tab = band_table(ch)
            if rec.quantity == "radiance":
                rad, tem = float(v), float(tab.temperature(np.array([v]))[0])
            else:
                rad, tem = float(tab.radiance(np.array([v]))[0]), float(v)
            out["channels"].append({"name": ch.name, "radiance": rad, "temperature_K": tem})
        maps = self.vm.overlay.frame_maps()
        if maps:
            cols = maps.get("column_density_kg_m2", {})
            out["column_density_kg_m2"] = {
                sp: float(np.asarray(c)[iy, ix]) for sp, c in cols.items()
            }
            if "velocity_px_per_frame" in maps:
                u, v = maps["velocity_px_per_frame"]
                out["velocity_px_per_frame"] = (
                    float(np.asarray(u)[iy, ix]),
                    float(np.asarray(v)[iy, ix]),
                )
                out["velocity_m_s"] = tuple(
                    c * self.px_per_frame_to_m_s() for c in out["velocity_px_per_frame"]
                )
            if "status" in maps:
                out["status"] = (
                    maps["status"][iy, ix].item()
                    if hasattr(maps["status"][iy, ix], "item")
                    else maps["status"][iy, ix]
                )
        return out
