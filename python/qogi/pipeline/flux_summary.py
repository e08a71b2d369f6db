"""What the uncertainty budget's checks need from one surface's columns and
velocities, summed over the blocks of a streamed run.

The pipeline streams a recording in blocks (docs/pipeline_api.md, "Time and
blocks"), so no (frames x samples) array of a whole run exists. The
line-shape term, the hot-gas bias, the rate-direction check and the
record-length advice each need only sums over frames, which
:class:`FluxSummary` keeps per surface and species:

* the flux ``c w`` (``w = v_n dl``) binned in ln c (2000 bins over 1e-9 ..
  1e2 kg/m2, 0.013 wide: any smooth function of the column, such as a
  line-shape rule's column ratio, is re-weighted from it to < 1e-4);
* per sample: the sum of the columns and of their variances over frames;
* the flux bound at a speed floor (``sum c max(|v_n|, floor) dl``), the
  column-weighted mean speed, and the line mass ``sum c dl``;
* the flux against the surface's orientation and the gross flux
  (``sum max(0, -c w)``, ``sum |c w|``: the flow's reversals,
  :mod:`qogi.pipeline.selfchecks`).
"""

from __future__ import annotations

import dataclasses
from typing import Optional

import numpy as np

__all__ = ["FluxSummary", "LN_EDGES"]

#: Bin edges in ln(column [kg/m2]).
LN_EDGES = np.linspace(np.log(1e-9), np.log(1e2), 2001)
_LN_CENTRES = 0.5 * (LN_EDGES[1:] + LN_EDGES[:-1])


@dataclasses.dataclass
class FluxSummary:
    """Sums over the frames of one surface and species (see the module)."""

    hist_cw: np.ndarray
    sum_c: np.ndarray
    sum_s2: np.ndarray
    frames: int = 0
    bound: float = 0.0
    speed_num: float = 0.0
    speed_den: float = 0.0
    mass_line: float = 0.0
    flux_against: float = 0.0
    flux_abs: float = 0.0

    @classmethod
    def empty(cls, n_samples: int) -> FluxSummary:
        return cls(np.zeros(len(_LN_CENTRES)), np.zeros(n_samples), np.zeros(n_samples))

    @classmethod
    def of(
        cls,
        c: np.ndarray,
        sig: np.ndarray,
        vn: np.ndarray,
        dl: np.ndarray,
        speed_floor: float = 0.0,
    ) -> FluxSummary:
        """The sums of one block: columns ``c`` and their 1-sigma ``sig``
        [kg/m2], normal velocity ``vn`` [m/s] (frames x samples), sample
        lengths ``dl`` [m]; ``speed_floor`` [m/s] the least speed the flux
        bound assumes (the direction check's)."""
        c = np.asarray(c, float)
        s = cls.empty(c.shape[1] if c.ndim == 2 else 0)
        if c.size == 0:
            return s
        vn = np.broadcast_to(np.asarray(vn, float), c.shape)
        v = np.where(np.isfinite(vn), vn, 0.0)
        w = v * dl[None, :]
        c0 = np.where(np.isfinite(c), c, 0.0)
        pos = np.isfinite(c) & (c > 0) & np.isfinite(vn)
        if pos.any():
            idx = np.clip(np.searchsorted(LN_EDGES, np.log(c[pos])) - 1, 0, len(_LN_CENTRES) - 1)
            s.hist_cw = np.bincount(idx, weights=(c * w)[pos], minlength=len(_LN_CENTRES))
        s.sum_c = c0.sum(axis=0)
        sg = np.where(np.isfinite(sig), sig, 0.0)
        s.sum_s2 = (sg**2).sum(axis=0)
        s.frames = int(c.shape[0])
        s.bound = float(np.sum(c0 * np.maximum(np.abs(v), speed_floor) * dl[None, :]))
        s.speed_num = float(np.sum(np.abs(v) * c0))
        s.speed_den = float(np.sum(c0))
        s.mass_line = float(np.sum(c0 * dl[None, :]))
        cw = c0 * w
        s.flux_against = float(np.sum(np.maximum(0.0, -cw)))
        s.flux_abs = float(np.sum(np.abs(cw)))
        return s

    def __iadd__(self, other: FluxSummary) -> FluxSummary:
        if other.frames == 0:
            return self
        if self.frames == 0:
            self.sum_c = np.zeros_like(other.sum_c)
            self.sum_s2 = np.zeros_like(other.sum_s2)
        self.hist_cw = self.hist_cw + other.hist_cw
        self.sum_c = self.sum_c + other.sum_c
        self.sum_s2 = self.sum_s2 + other.sum_s2
        self.frames += other.frames
        self.bound += other.bound
        self.speed_num += other.speed_num
        self.speed_den += other.speed_den
        self.mass_line += other.mass_line
        self.flux_against += other.flux_against
        self.flux_abs += other.flux_abs
        return self

    def flux_ratios(self, grid_columns: np.ndarray, ratios: np.ndarray) -> list:
        """The flux re-weighted by each row r of ``ratios`` (a function of the
        column tabulated at ``grid_columns``, interpolated in ln c):
        ``sum(c r(c) w) / sum(c w)``; 1.0 where there is no flux."""
        rows = np.atleast_2d(ratios)
        flux = float(self.hist_cw.sum())
        if flux == 0.0 or len(grid_columns) < 2:
            return [1.0] * len(rows)
        g = np.log(np.asarray(grid_columns, float))
        x = np.clip(_LN_CENTRES, g[0], g[-1])
        return [float(np.sum(self.hist_cw * np.interp(x, g, r))) / flux for r in rows]

    def mean_speed(self) -> float:
        """Column-weighted mean |v_n| [m/s] (0 without columns)."""
        return self.speed_num / self.speed_den if self.speed_den > 0 else 0.0

    def direction(self, mean_rate_kg_s: float) -> Optional[dict]:
        """Whether the rate contradicts the gas crossing the surface: None
        when consistent, else ``{"reason": "zero"|"against", "bound_kg_s"}``
        (gas crosses where the time-averaged column stands 3 sigma above its
        noise; the bound is the flux the columns carry at the floored speed,
        all taken as outgoing, per frame)."""
        nt = max(1, self.frames)
        mean_c = self.sum_c / nt
        noise = np.sqrt(self.sum_s2) / nt
        if not (
            mean_c.size and np.any(mean_c > 3.0 * np.maximum(noise, 1e-300)) and mean_c.max() > 0
        ):
            return None
        bound = self.bound / nt
        mean = float(mean_rate_kg_s)
        if mean == 0.0 or not np.isfinite(mean):
            return {"reason": "zero", "bound_kg_s": bound}
        if mean < 0:
            return {"reason": "against", "bound_kg_s": max(bound, abs(mean))}
        return None
