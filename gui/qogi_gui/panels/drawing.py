"""Drawing on the image: control surfaces, the background region and the
source, by mouse (:meth:`SurfaceEditor.click`) or typed."""

from __future__ import annotations

import math
from typing import List, Optional, Sequence, Tuple

from ..settings import BACKGROUNDS
from ..surfaces import SURFACE_COLOURS, RegionDraft, SurfaceDraft

__all__ = ["SurfaceEditor", "MODES"]

#: Interaction modes of the image: look (pan/zoom/read-out), draw a line (two
#: clicks), draw a polyline (clicks, right-click or Enter to finish), pick the
#: background region (two corners), pick the source, edit (drag vertices).
MODES = ("view", "line", "polyline", "region", "source", "edit")


class SurfaceEditor:
    """The Surfaces tab: the drawn surfaces (in order), the one being drawn,
    the selection, the background region and the interaction mode."""

    def __init__(self, vm):
        self.vm = vm
        self.mode = "view"
        self.surfaces: List[SurfaceDraft] = []
        self.drawing: Optional[SurfaceDraft] = None
        self.selected: Optional[int] = None
        self.region: Optional[RegionDraft] = None
        self._corner: Optional[Tuple[float, float]] = None

    def reset(self, recording) -> None:
        self.surfaces, self.drawing, self.selected, self.region = [], None, None, None
        self.mode = "view"

    def _changed(self) -> None:
        """The drawn surfaces changed."""
        self.vm.rev["surfaces"] += 1
        self.vm.run.inputs_changed()

    def set_mode(self, mode: str) -> bool:
        """Switch what a click on the image does (see :data:`MODES`)."""
        if mode not in MODES:
            return self.vm.log.error(f"unknown mode {mode!r}; modes: {', '.join(MODES)}")
        if self.drawing is not None and mode != self.mode:
            self.finish_drawing(quiet=True)
        self._corner = None
        self.mode = mode
        self.vm.rev["surfaces"] += 1
        return True

    def _inside(self, x: float, y: float) -> bool:
        """On the image as displayed (pixel squares included)."""
        r = self.vm.recording
        return r is not None and -0.5 <= x <= r.width - 0.5 and -0.5 <= y <= r.height - 0.5

    def _snap(self, x: float, y: float) -> Tuple[float, float]:
        """A point on the image kept within the outermost pixel centres
        ([0, W-1] x [0, H-1]), where the pipeline can sample it."""
        r = self.vm.recording
        return (min(max(float(x), 0.0), r.width - 1.0), min(max(float(y), 0.0), r.height - 1.0))

    def click(self, x: float, y: float, button: str = "left", tolerance_px: float = 4.0) -> bool:
        """A click on the image at pixel coordinates (x, y), by mode: add a
        surface point; finish a polyline (right button); set a region corner;
        set the source; select the surface nearest the click."""
        vm = self.vm
        if vm.recording is None:
            return vm.log.error("open a recording (or the demo) before drawing")
        if button == "right":
            if self.mode == "polyline" and self.drawing is not None:
                return self.finish_drawing()
            return False
        if not self._inside(x, y):
            return vm.log.error(f"({x:.1f}, {y:.1f}) is outside the image: click on the frame")
        x, y = self._snap(x, y)
        if self.mode in ("line", "polyline"):
            if self.drawing is None:
                n = len(self.surfaces)
                self.drawing = SurfaceDraft(
                    self._new_name(), colour=SURFACE_COLOURS[n % len(SURFACE_COLOURS)]
                )
            if self.drawing.points and math.dist(self.drawing.points[-1], (x, y)) < 1e-6:
                return vm.log.error("that point repeats the previous one: click somewhere else")
            self.drawing.points.append((float(x), float(y)))
            vm.rev["surfaces"] += 1
            if self.mode == "line" and len(self.drawing.points) == 2:
                return self.finish_drawing()
            return True
        if self.mode == "region":
            if self._corner is None:
                self._corner = (float(x), float(y))
                vm.rev["surfaces"] += 1
                return True
            region = RegionDraft.from_corners(
                self._corner, (x, y), vm.recording.width, vm.recording.height
            )
            self._corner = None
            if region.n_pixels < 1:
                return vm.log.error("the region holds no pixel centre: drag a larger rectangle")
            return self.set_region(region)
        if self.mode == "source":
            vm.form.set_source(x, y)
            vm.log.info(
                f"source set at ({x:.1f}, {y:.1f}) px: surfaces are oriented so that "
                "flow away from it counts positive"
            )
            return True
        # view / edit: select the nearest surface
        best = None
        for i, s in enumerate(self.surfaces):
            d = s.distance_to((x, y))
            if d <= tolerance_px and (best is None or d < best[1]):
                best = (i, d)
        self.selected = best[0] if best else None
        vm.rev["surfaces"] += 1
        return best is not None

    def _new_name(self) -> str:
        names = {s.name for s in self.surfaces}
        k = len(self.surfaces) + 1
        while f"S{k}" in names:
            k += 1
        return f"S{k}"

    @property
    def region_corner(self) -> Optional[Tuple[float, float]]:
        """The first corner of a region being picked, or None."""
        return self._corner

    def finish_drawing(self, quiet: bool = False) -> bool:
        """Complete the surface being drawn (>= 2 distinct points), or drop it."""
        d, self.drawing = self.drawing, None
        self.vm.rev["surfaces"] += 1
        if d is None:
            return False
        if not d.complete:
            if not quiet:
                self.vm.log.error("a surface needs at least two distinct points: it was not kept")
            return False
        self.surfaces.append(d)
        self.selected = len(self.surfaces) - 1
        self.vm.run.inputs_changed()
        self.vm.log.info(
            f"surface {d.name} drawn ({len(d.points)} points); the arrow shows the "
            "direction counted positive"
        )
        return True

    def cancel_drawing(self) -> None:
        self.drawing, self._corner = None, None
        self.vm.rev["surfaces"] += 1

    def undo_point(self) -> None:
        """Remove the last point of the surface being drawn."""
        if self.drawing is not None and self.drawing.points:
            self.drawing.points.pop()
            if not self.drawing.points:
                self.drawing = None
            self.vm.rev["surfaces"] += 1

    def add_surface(self, points, name: str = "") -> bool:
        """Add a surface from typed points [(x, y), ...] (all inside the image)."""
        vm = self.vm
        if vm.recording is None:
            return vm.log.error("open a recording before adding surfaces")
        try:
            pts = [(float(x), float(y)) for x, y in points]
        except (TypeError, ValueError):
            return vm.log.error(f"surface points must be (x, y) pairs of numbers; got {points!r}")
        r = vm.recording
        bad = [p for p in pts if not (0 <= p[0] <= r.width - 1 and 0 <= p[1] <= r.height - 1)]
        if bad:
            return vm.log.error(
                f"surface point {bad[0]} is outside the image: x must be in "
                f"[0, {r.width - 1}] and y in [0, {r.height - 1}] px"
            )
        n = len(self.surfaces)
        d = SurfaceDraft(
            name.strip() or self._new_name(), pts, SURFACE_COLOURS[n % len(SURFACE_COLOURS)]
        )
        if not d.complete:
            return vm.log.error("a surface needs at least two distinct points")
        if any(s.name == d.name for s in self.surfaces):
            return vm.log.error(f"a surface named {d.name!r} exists already")
        self.surfaces.append(d)
        self.selected = n
        self._changed()
        return True

    def auto_surfaces(self, distances_px: Sequence[float] = (30.0, 60.0, 90.0)) -> bool:
        """Detect the plume (qogi.plume_image of the first 50 frames) and add
        straight surfaces across it at these distances from its source
        (qogi.auto_surfaces); without a source set, the detected one is set
        too (it orients the surfaces and gives the velocimetry its flux level)."""
        import qogi

        vm = self.vm
        if vm.recording is None:
            return vm.log.error("open a recording before placing surfaces")
        try:
            dists = [float(d) for d in distances_px]
        except (TypeError, ValueError):
            return vm.log.error(f"distances must be numbers of pixels; got {distances_px!r}")
        if not dists or any(not (d > 0) for d in dists):
            return vm.log.error("give one or more distances > 0 px, e.g. 30, 60, 90")
        source = vm.form.source_point()
        from qogi.diagnostics import Diagnostics

        placed = Diagnostics()
        try:
            found, src = qogi.auto_surfaces(
                qogi.plume_image(vm.recording),
                dists,
                source=source,
                return_source=True,
                warnings=placed,
            )
        except ValueError as e:
            return vm.log.error(f"automatic surfaces: {e}")
        for w in placed:
            vm.log.info(f"warning: {w.message}")
        r = vm.recording
        added = 0
        for surf in found:
            pts = [
                (min(max(x, 0.0), r.width - 1.0), min(max(y, 0.0), r.height - 1.0))
                for x, y in surf.points
            ]
            name = surf.name
            k = 2
            while any(s.name == name for s in self.surfaces):
                name = f"{surf.name} {k}"
                k += 1
            if self.add_surface(pts, name):
                added += 1
        if source is None:
            vm.form.set_source(*src)
            vm.rev["surfaces"] += 1
        vm.log.info(
            f"{added} surface(s) placed across the plume at "
            f"{', '.join(f'{d:g}' for d in dists)} px from the source at "
            f"({src[0]:.1f}, {src[1]:.1f}) px"
        )
        return added > 0

    def _surface(self, index: int) -> Optional[SurfaceDraft]:
        if not 0 <= index < len(self.surfaces):
            self.vm.log.error(f"there is no surface {index + 1} (there are {len(self.surfaces)})")
            return None
        return self.surfaces[index]

    def move_vertex(self, index: int, vertex: int, x: float, y: float) -> bool:
        """Move one point of a surface (edit mode); kept inside the image."""
        s = self._surface(index)
        if s is None:
            return False
        if not 0 <= vertex < len(s.points):
            return self.vm.log.error(f"surface {s.name} has no point {vertex}")
        x, y = self._snap(x, y)
        others = s.points[:vertex] + s.points[vertex + 1 :]
        if any(math.dist(p, (x, y)) < 1e-6 for p in others):
            return self.vm.log.error("two points of a surface cannot coincide")
        s.points[vertex] = (x, y)
        self._changed()
        return True

    def delete_surface(self, index: int) -> bool:
        s = self._surface(index)
        if s is None:
            return False
        del self.surfaces[index]
        self.selected = None
        self._changed()
        self.vm.log.info(f"surface {s.name} deleted")
        return True

    def reverse_surface(self, index: int) -> bool:
        """Walk a surface the other way: flips the direction counted positive."""
        s = self._surface(index)
        if s is None:
            return False
        self.surfaces[index] = s.reversed()
        self._changed()
        return True

    def rename_surface(self, index: int, name: str) -> bool:
        s = self._surface(index)
        if s is None:
            return False
        name = str(name).strip()
        if not name:
            return self.vm.log.error("a surface needs a name")
        if any(o.name == name for i, o in enumerate(self.surfaces) if i != index):
            return self.vm.log.error(f"a surface named {name!r} exists already")
        s.name = name
        self._changed()
        return True

    def set_region(self, region: Optional[RegionDraft]) -> bool:
        """Set (or clear with None) the background region; choosing one
        switches the background setting to it."""
        vm = self.vm
        settings = vm.form.settings
        if region is not None:
            r = vm.recording
            if r is None:
                return vm.log.error("open a recording before picking a region")
            if not (
                0 <= region.x0 < region.x1 <= r.width and 0 <= region.y0 < region.y1 <= r.height
            ):
                return vm.log.error(
                    f"region {region.as_tuple()} is not a rectangle inside the "
                    f"{r.width}x{r.height} image"
                )
            settings.background = "region"
            vm.log.info(
                f"background region x {region.x0}..{region.x1 - 1}, y {region.y0}.."
                f"{region.y1 - 1} ({region.n_pixels} pixels)"
            )
        elif settings.background == "region":
            settings.background = BACKGROUNDS[0]
        self.region = region
        vm.rev["settings"] += 1
        self._changed()
        return True
