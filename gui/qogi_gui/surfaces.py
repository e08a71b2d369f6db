"""Control surfaces and the background region as the user draws them.

Coordinates are the recording contract's pixel coordinates: x right, y down,
origin at the centre of the top-left pixel, floats allowed; the image spans
[-0.5, W - 0.5] x [-0.5, H - 0.5] and surface points are kept within the
outermost pixel centres, [0, W - 1] x [0, H - 1].

Sign convention (docs/pipeline_api.md): flux through a surface is positive
along its **left-hand normal** when walking from its first point to its last
in the image as displayed. With y down, the left of a walking direction
(tx, ty) is (ty, -tx): a horizontal line drawn left to right counts upward
flow (towards smaller y) as positive. :func:`flow_arrow` gives the arrow the
viewer draws to show that direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import List, Optional, Sequence, Tuple

__all__ = [
    "SurfaceDraft",
    "RegionDraft",
    "left_normal",
    "flow_arrow",
    "polyline_length",
    "point_segment_distance",
    "SURFACE_COLOURS",
]

Point = Tuple[float, float]

#: Colours (RGB 0-255) given to surfaces in drawing order, repeated.
SURFACE_COLOURS = (
    (0, 220, 255),
    (255, 200, 0),
    (120, 255, 90),
    (255, 90, 200),
    (255, 255, 255),
    (255, 130, 40),
)


@dataclass
class SurfaceDraft:
    """A control surface being drawn or edited (a polyline of >= 2 points).

    Attributes
    ----------
    name : str
    points : list of (x, y), pixels
    colour : (r, g, b), 0-255
    """

    name: str
    points: List[Point] = field(default_factory=list)
    colour: Tuple[int, int, int] = SURFACE_COLOURS[0]

    @property
    def complete(self) -> bool:
        return len(self.points) >= 2 and polyline_length(self.points) > 0

    def reversed(self) -> SurfaceDraft:
        """The same surface walked the other way (the positive flux direction flips)."""
        return SurfaceDraft(self.name, list(reversed(self.points)), self.colour)

    def distance_to(self, p: Point) -> float:
        """Shortest distance [px] from ``p`` to the polyline."""
        if not self.points:
            return math.inf
        if len(self.points) == 1:
            return math.dist(self.points[0], p)
        return min(
            point_segment_distance(p, a, b) for a, b in zip(self.points[:-1], self.points[1:])
        )

    def nearest_vertex(self, p: Point) -> Tuple[int, float]:
        """(index, distance [px]) of the vertex closest to ``p``."""
        d = [math.dist(q, p) for q in self.points]
        i = min(range(len(d)), key=d.__getitem__)
        return i, d[i]


@dataclass
class RegionDraft:
    """The background region: a pixel rectangle [x0, x1) x [y0, y1) (ints,
    inclusive-exclusive, as ``qogi.Region``)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @classmethod
    def from_corners(cls, a: Point, b: Point, width: int, height: int) -> RegionDraft:
        """The pixels whose centres lie in the rectangle spanned by two clicked
        corners, limited to the image."""
        (ax, ay), (bx, by) = a, b
        x0 = max(0, math.ceil(min(ax, bx) - 1e-9))
        y0 = max(0, math.ceil(min(ay, by) - 1e-9))
        x1 = min(width, math.floor(max(ax, bx) + 1e-9) + 1)
        y1 = min(height, math.floor(max(ay, by) + 1e-9) + 1)
        return cls(int(x0), int(y0), int(x1), int(y1))

    @property
    def n_pixels(self) -> int:
        return max(0, self.x1 - self.x0) * max(0, self.y1 - self.y0)

    def as_tuple(self) -> Tuple[int, int, int, int]:
        return self.x0, self.y0, self.x1, self.y1


def polyline_length(points: Sequence[Point]) -> float:
    return sum(math.dist(a, b) for a, b in zip(points[:-1], points[1:]))


def point_segment_distance(p: Point, a: Point, b: Point) -> float:
    """Distance from ``p`` to the segment ``a``-``b``."""
    (px, py), (ax, ay), (bx, by) = p, a, b
    dx, dy = bx - ax, by - ay
    L2 = dx * dx + dy * dy
    t = 0.0 if L2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / L2))
    return math.hypot(px - (ax + t * dx), py - (ay + t * dy))


def left_normal(a: Point, b: Point) -> Point:
    """Unit left-hand normal of walking from ``a`` to ``b`` in the image as
    displayed (x right, y down): (ty, -tx) for the unit direction (tx, ty)."""
    dx, dy = b[0] - a[0], b[1] - a[1]
    n = math.hypot(dx, dy)
    if n == 0:
        raise ValueError(f"points {a} and {b} coincide: a segment needs two distinct points")
    return dy / n, -dx / n


def flow_arrow(points: Sequence[Point], length: float) -> Optional[Tuple[Point, Point]]:
    """(tail, head) of the arrow showing the positive flux direction: from the
    point halfway along the polyline (by length), ``length`` pixels along the
    left-hand normal of the segment it lies on. None for an incomplete surface."""
    if len(points) < 2:
        return None
    total = polyline_length(points)
    if total <= 0:
        return None
    half = 0.5 * total
    run = 0.0
    for a, b in zip(points[:-1], points[1:]):
        seg = math.dist(a, b)
        if seg > 0 and run + seg >= half:
            t = (half - run) / seg
            mid = (a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]))
            nx, ny = left_normal(a, b)
            return mid, (mid[0] + length * nx, mid[1] + length * ny)
        run += seg
    return None
