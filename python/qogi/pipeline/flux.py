"""Stage 4, the flux (thesis eq. 12): ``F = sum_k c_k (v_k . n_k) dl_k``
along each surface, per frame and species, with the sums the budget and its
checks need (:class:`~.state.SurfaceFlux`); :func:`block_flux` makes a
block's :class:`~.state.BlockOut` from its columns and normal velocities.
"""

from __future__ import annotations

import math
from typing import List, Optional

import numpy as np

from .. import _engine
from ..measure.flux import surface_rate
from .detection import frame_widths, velocity_sums
from .flux_summary import FluxSummary
from .state import BlockColumns, BlockOut, Flow, RunState, SurfaceFlux

__all__ = ["block_flux", "block_maps"]


def block_flux(
    st: RunState, blk, cols: BlockColumns, vn: Optional[List[np.ndarray]], flows: Optional[Flow]
) -> BlockOut:
    """The kept frames of a block (its overlap with the neighbours left
    out): each surface's and species' :class:`SurfaceFlux` from the columns
    and the normal velocities ``vn`` [m/s] (per surface, (frames, samples)).
    A cancelled block has no velocity (``vn`` None): zero there (its rates
    are the columns' only; the partial result says so with complete=False)."""
    cfg = st.cfg
    k0 = blk.offset
    k1 = max(k0, min(k0 + blk.n_keep, cols.done))
    flux = []
    for j, (xy, _n, dl, _t) in enumerate(st.samples):
        v = np.zeros((k1 - k0, len(xy))) if vn is None else vn[j][k0:k1]
        flux.append(
            {
                sp: _surface_flux(
                    cols.columns[j][sp][k0:k1],
                    cols.sigmas[j][sp][k0:k1],
                    v,
                    dl,
                    _speed_floor(st, flows, j, sp),
                )
                for sp in cfg.species
            }
        )
    return BlockOut(flux, k1 - k0, cols.counts, {}, cols.info, cols.cancelled)


def block_maps(st: RunState, blk, cols: BlockColumns, flows: Flow) -> dict:
    """Maps (every tenth of the run) keyed by the recording's frame index,
    the velocity back in the whole region: NaN outside the part where the
    flow was computed (``velocity_region``: x0, y0, x1, y1 in the maps'
    pixels, end exclusive), which has no velocity, not a zero one."""
    a = blk.read[0]
    first = st.start + a
    col_fields = cols.fields
    maps = {}
    fu, fv, (cx, cy) = flows.u, flows.v, flows.origin
    region = (int(cx), int(cy), int(cx) + fu.shape[2], int(cy) + fu.shape[1])
    for k in range(blk.offset, blk.offset + blk.n_keep):
        if (a + k) % st.map_every:
            continue
        uv = tuple(np.full(col_fields.shape[1:], np.nan, np.float32) for _ in range(2))
        for full, p in zip(uv, (fu[k], fv[k])):
            full[cy : cy + p.shape[0], cx : cx + p.shape[1]] = p
        maps[first + k] = {
            "column_density_kg_m2": {st.cfg.species[0]: col_fields[k].copy()},
            "velocity_px_per_frame": uv,
            "velocity_region": region,
            "origin": (st.roi.x0, st.roi.y0),
        }
    return maps


def _surface_flux(
    c: np.ndarray, sig: np.ndarray, vn: np.ndarray, dl: np.ndarray, speed_floor: float = 0.0
) -> SurfaceFlux:
    """Thesis eq. 12 per frame: sum over the samples of column c [kg/m2] x
    normal velocity vn [m/s] x length dl [m], (frames, samples) arrays;
    ``speed_floor`` [m/s] the direction check's least speed."""

    r = surface_rate(c, sig, vn, dl)  # the engine's flux module (cpp/engine/flux)
    cv, cs, vmed = velocity_sums(c, np.broadcast_to(vn, c.shape))
    return SurfaceFlux(
        r.rate,
        r.samples,
        r.column_variance,
        cv,
        cs,
        vmed,
        frame_widths(c, dl),
        FluxSummary.of(c, sig, vn, dl, speed_floor),
    )


def _speed_floor(st: RunState, flows: Optional[Flow], j: int, species: str) -> float:
    """The least speed [m/s] the direction check's flux bound assumes on
    surface j in a block: the flow's 90th-percentile speed, the buoyancy
    scale sqrt(g' width) (a plume moves at least about that fast where its own
    buoyancy drives it), so a dead flow cannot make the bound vanish, and,
    when the block found its transport only the other way (``Flow.reverse_speed``:
    gas moving towards the given source), that transport's speed on the
    surface's lines (median over its samples)."""

    scene = st.scene
    typical = 0.0
    if flows is not None:
        fu, fv = flows.u, flows.v
        if len(fu):
            step = max(1, len(fu) // 20)
            typical = (
                float(np.nanpercentile(np.hypot(fu[::step], fv[::step]), 90))
                * scene.m_s_per_px_frame
            )
        if flows.reverse_speed is not None and st.transport is not None:
            xy = st.samples[j][0]
            along = st.transport.axis in ("up", "down")
            line = np.rint((xy[:, 1] - st.roi.y0) if along else (xy[:, 0] - st.roi.x0))
            rs = flows.reverse_speed
            ok = (line >= 0) & (line < len(rs))
            speeds = rs[line[ok].astype(int)]
            speeds = speeds[np.isfinite(speeds)]
            if speeds.size:
                typical = max(typical, float(np.median(speeds)) * scene.m_s_per_px_frame)
    g_reduced = 9.81 * abs(
        1.0 - _engine.molar_mass(species) * scene.ambient_K / (0.028965 * scene.gas_K)
    )
    sigma_m = getattr(st.columns, "sigma_m", {}).get(j) or 0.02
    return max(typical, math.sqrt(g_reduced * 2.3548 * sigma_m))
