"""The result on the video: column-density overlay and velocity vectors of the
shown frame, from the per-pixel maps the run kept."""

from __future__ import annotations

from typing import Dict, List, Optional, Tuple

import numpy as np

from .. import display, results

__all__ = ["Overlay"]


class Overlay:
    """Maps of the result (``vm.run.result``) at the shown frame."""

    def __init__(self, vm):
        self.vm = vm
        self._buffer: Optional[np.ndarray] = None
        self._vmax: Dict[str, float] = {}
        self._maps_cache: tuple = (None, None)
        self._map_frames: tuple = (None, [])

    def reset(self, rec) -> None:
        self._vmax.clear()
        self._buffer = np.zeros((rec.height, rec.width, 4), np.float32)

    def new_result(self) -> None:
        """A new result: its colour scale is measured afresh."""
        self._vmax.clear()

    def frame_maps(self) -> Optional[dict]:
        """The result's per-pixel maps of the shown frame (full-frame arrays), or None."""
        vm = self.vm
        if vm.run.result is None:
            return None
        key = (vm.rev["result"], vm.player.frame)
        if self._maps_cache[0] != key:
            self._maps_cache = (
                key,
                results.frame_maps(
                    vm.run.result, vm.player.frame, (vm.recording.height, vm.recording.width)
                ),
            )
        return self._maps_cache[1]

    def species(self) -> Optional[str]:
        """The species the overlay shows (the chosen one if the result has it)."""
        names = self.vm.run.result_species()
        if not names:
            return None
        chosen = self.vm.video.display.overlay_species
        return chosen if chosen in names else names[0]

    def map_frames(self) -> List[int]:
        """Frames for which the result kept per-pixel maps (the pipeline may keep
        them for a subset of the frames only)."""
        vm = self.vm
        if vm.run.result is None:
            return []
        if self._map_frames[0] != vm.rev["result"]:
            kept = results.map_frame_keys(vm.run.result)
            self._map_frames = (vm.rev["result"], sorted(kept))
        return self._map_frames[1]

    def seek_map_frame(self, direction: int = 1) -> bool:
        """Show the next (direction > 0) or previous frame that has maps."""
        frames = self.map_frames()
        if not frames:
            return self.vm.log.error(
                "the result holds no per-pixel maps: run with 'keep per-pixel maps' ticked"
            )
        player = self.vm.player
        later = (
            [f for f in frames if f > player.frame]
            if direction > 0
            else [f for f in frames if f < player.frame]
        )
        target = (
            (later[0] if direction > 0 else later[-1])
            if later
            else (frames[0] if direction > 0 else frames[-1])
        )
        player.playing = False
        player.seek(target)
        return True

    def vmax(self) -> float:
        """Top of the column-density colour scale [kg/m2] (fixed per result and species)."""
        sp = self.species()
        if sp is None:
            return 0.0
        if sp not in self._vmax:
            kept = self.map_frames()
            frames = (
                [kept[int(i)] for i in np.linspace(0, len(kept) - 1, min(8, len(kept))).round()]
                if kept
                else []
            )
            rec = self.vm.recording
            self._vmax[sp] = results.overlay_scale(
                self.vm.run.result, sp, frames, (rec.height, rec.width)
            )
        return self._vmax[sp]

    def detectability(self) -> Optional[Tuple[np.ndarray, float, float]]:
        """The result's minimum-detectable column map of the overlay species
        [kg/m2] and its colour range (2nd and 98th percentiles of the finite
        pixels), or None when the result has none (truth columns)."""
        result, sp = self.vm.run.result, self.species()
        if result is None or sp not in result.min_detectable_column_species:
            return None
        mdc = result.min_detectable_column(sp)
        finite = mdc[np.isfinite(mdc)]
        if not finite.size:
            return mdc, 0.0, 0.0
        lo, hi = np.percentile(finite, [2, 98])
        return mdc, float(lo), float(max(hi, lo * 1.001))

    def render(self) -> Optional[np.ndarray]:
        """The overlay as RGBA (H, W, 4): the shown frame's column density,
        transparent where there is no gas, or the run's minimum-detectable
        column (``DisplayState.overlay_kind``); None when hidden or not
        available."""
        d = self.vm.video.display
        if not d.show_overlay or self.vm.run.result is None:
            return None
        if d.overlay_kind == display.OVERLAY_KINDS[1]:
            got = self.detectability()
            if got is None:
                return None
            mdc, lo, hi = got
            shown = np.where(np.isfinite(mdc), mdc, np.nan).astype(np.float32)
            out = display.colorize(
                shown, lo, hi, display.colormap_lut(d.overlay_colormap), out=self._buffer
            )
            out[..., 3] = np.where(np.isfinite(mdc), 0.6, 0.0)  # no contrast: the video
            return out
        maps = self.frame_maps()
        sp = self.species()
        if not maps or sp is None:
            return None
        col = maps.get("column_density_kg_m2", {}).get(sp)
        vmax = self.vmax()
        if col is None or not vmax > 0:
            return None
        return display.colorize_overlay(
            col, vmax, display.colormap_lut(d.overlay_colormap), out=self._buffer
        )

    def vectors(self, spacing: int = 12) -> Tuple[np.ndarray, np.ndarray, float]:
        """Velocity arrows (tails, heads, scale) of the shown frame where the
        overlay species has gas; empty when hidden or not available."""
        empty = (np.zeros((0, 2)), np.zeros((0, 2)), 0.0)
        if not self.vm.video.display.show_vectors or self.vm.run.result is None:
            return empty
        maps = self.frame_maps()
        if not maps or "velocity_px_per_frame" not in maps:
            return empty
        u, v = maps["velocity_px_per_frame"]
        sp = self.species()
        col = maps.get("column_density_kg_m2", {}).get(sp) if sp else None
        vmax = self.vmax()
        return results.vector_field(
            u, v, weight=col, spacing=spacing, min_weight=0.05 * vmax if col is not None else 0.0
        )
