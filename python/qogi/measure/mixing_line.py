"""Column densities with the gas temperature inferred on the plume's mixing line.

A released gas that mixes with the ambient air (adiabatically, as in a plume)
has, at every point, a temperature excess proportional to its volume
fraction: ``T - T_amb = k x`` (the Gaussian line-of-sight model has this
shape: both follow g(s)). One k holds for the whole scene, so it is measured
once (:meth:`MixingLineSolver.slope`): on a random sample (<= 3000) of the
pixel-frames with contrast >= 10x noise solved on the line for each k of a
10 K grid, k minimises the summed chi2 (each pixel's capped at 50), refined
by a parabola; its 1-sigma is where that profile rises by the reduced chi2.
Then each pixel-frame has one unknown, x, with ``T_peak = T_amb + k x``
(:meth:`MixingLineSolver.solve`): with a known composition (or one species)
its least-squares value on the line (:func:`qogi.inversion.invert_on_mixing_line`:
a coarse scan and Gauss-Newton in ln x on the scene table, ~40,000 px/s per
core); otherwise a root of ``x = g(x)`` (g: the fixed-temperature inversion
at T(x)) by bracketed regula falsi, each step one fast fixed-temperature pass
over the pixels not yet converged. This avoids the two-branch (thin-hot /
thick-cool) ambiguity of free per-pixel temperatures in noisy frames and
costs one line solve instead of a multi-start four-parameter solve per pixel.
The uncertainty of k is carried into the column densities by
:meth:`MixingLineSolver.slope_effect`.
"""

from __future__ import annotations

import math
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

from ..physics.forward import ForwardModel
from ..progress import fraction_part
from . import inversion as inv

__all__ = ["MixingLineSolver"]

Progress = Optional[Callable[[float], Any]]


class MixingLineSolver:
    """The mixing-line inversion of one set of pixel-frames.

    Parameters
    ----------
    model : ForwardModel
        The channels' forward model.
    table : scene table
        :func:`qogi.inversion.scene_table` of ``model`` for the scene.
    radiance, background : (C, P) arrays, W/(m2 sr)
        Band radiance and background of P pixel-frames.
    sigma_m : (P,) array, m
        Plume depth of each pixel-frame.
    ambient_K : float, K
        Ambient temperature (the line's origin).
    temperature_range_K : (float, float), K
        Bounds of the peak temperature.
    species : sequence of str
        The inverted species.
    composition : dict of str -> float, optional
        Known mole-fraction ratios; with one species it is implied.
    inversion_options : dict
        ``netd_K``, ``fractions`` and ``num_threads`` of the inversion (and
        optionally ``signed_below_detection``, :class:`qogi.inversion.Inversion`'s).
    """

    def __init__(
        self,
        model: ForwardModel,
        table,
        radiance: np.ndarray,
        background: np.ndarray,
        sigma_m: np.ndarray,
        *,
        ambient_K: float,
        temperature_range_K: Tuple[float, float],
        species: Sequence[str],
        composition: Optional[Mapping[str, float]],
        inversion_options: Dict[str, Any],
    ):
        self.model, self.table = model, table
        self.r2, self.b2, self.s2 = radiance, background, sigma_m
        self.ambient_K = float(ambient_K)
        self.lo, self.hi = temperature_range_K
        self.species = tuple(species)
        self.kw = dict(inversion_options)
        self.netd_K = self.kw["netd_K"]
        self.num_threads: int = self.kw.get("num_threads") or 0
        # With a known composition (or one species) each pixel-frame is one
        # least-squares problem on the line (the engine's mixing-line
        # inverter); otherwise the fixed-point passes.
        self.composition = dict(composition) if composition else None
        if self.composition is None and len(self.species) == 1:
            self.composition = {self.species[0]: 1.0}
        self._fixed: List[Any] = []  # the fixed-temperature inversion, made on use

    # ------------------------------------------------------------------ the slope
    def slope(self, progress: Progress = None) -> Optional[inv.MixingLineSlope]:
        """The mixing line's slope k [K per unit fraction]: the scene
        parameter that minimises the total chi2 of a sample of the detected
        pixel-frames (<= 3000, contrast >= 10x noise) solved on the line (a
        profile likelihood over a 10 K grid of k, refined by a parabola;
        engine: :func:`qogi.inversion.mixing_line_slope`). Pixel-by-pixel free
        temperatures are too weakly determined (and two-branched) to average
        into k. Without a known composition the engine chooses the sample and
        reads k off the profile; the fixed-point passes solve it on the line.
        None when too few pixel-frames qualify."""
        if self.composition is not None:
            return inv.mixing_line_slope(
                self.model,
                self.table,
                self.r2,
                self.b2,
                self.s2,
                netd_K=self.netd_K,
                composition=self.composition,
                num_threads=self.num_threads,
                progress=progress,
            )
        cand, _ = inv.mixing_line_slope_sample(
            self.model, self.table, self.r2, self.b2, netd_K=self.netd_K
        )
        if cand.size < 5:
            return None
        grid = np.arange(self.lo - self.ambient_K, self.hi - self.ambient_K + 1e-9, 10.0)
        chi = [
            self.solve(
                float(kk), cand, fraction_part(progress, i / grid.size, (i + 1) / grid.size)
            ).chi2
            for i, kk in enumerate(grid)
        ]
        return inv.mixing_line_slope_from_profile(grid, np.asarray(chi))

    # ------------------------------------------------------------------ the pixels
    def solve(self, k: float, idx: np.ndarray, progress: Progress = None) -> inv.InversionResult:
        """Every pixel-frame ``idx`` solved on the line of slope ``k``."""
        if self.composition is not None:
            return inv.invert_on_mixing_line(
                self.model,
                self.table,
                k,
                self.r2[:, idx],
                self.b2[:, idx],
                self.s2[idx],
                netd_K=self.netd_K,
                composition=self.composition,
                signed_below_detection=bool(self.kw.get("signed_below_detection", False)),
                num_threads=self.num_threads,
                progress=progress,
            )
        return self._solve_passes(k, idx, progress)

    def slope_effect(
        self,
        result: inv.InversionResult,
        k: float,
        k_sigma: float,
        idx: np.ndarray,
        progress: Progress = None,
    ) -> float:
        """Relative change of the summed column densities of pixel-frames
        ``idx`` (of ``result``, solved at ``k``) when k moves by its 1-sigma:
        the slope's uncertainty in the column-density term (0 without one)."""
        if not k_sigma > 0:
            return 0.0
        base = sum(result.column_density[sp][idx].sum() for sp in self.species)
        alt = self.solve(k + k_sigma, idx, progress)
        other = sum(alt.column_density[sp].sum() for sp in self.species)
        return float(abs(other - base) / base) if base > 0 else 0.0

    def _fixed_temperature(self) -> inv.Inversion:
        if not self._fixed:
            kw = {key: v for key, v in self.kw.items() if key != "temperature"}
            self._fixed.append(
                inv.Inversion(
                    self.model,
                    self.ambient_K,
                    temperature=inv.fixed(self.ambient_K),
                    sigma_m=0.05,
                    temperature_range_K=(self.lo, self.hi),
                    table=self.table,
                    **kw,
                )
            )
        return self._fixed[0]

    def _g(self, xv, kk, idx, progress):
        """The fixed-temperature inversion at ``T = T_amb + k x`` and the sum
        of its species' fractions."""
        t = np.clip(self.ambient_K + kk * xv, self.lo, self.hi)
        res = self._fixed_temperature().invert(
            self.r2[:, idx],
            background_radiance=self.b2[:, idx],
            sigma_m=self.s2[idx],
            peak_temperature_K=t,
            progress=progress,
        )
        return res, sum(res.peak_fraction[sp] for sp in self.species)

    def _solve_passes(self, kk, idx, progress, passes=7):
        """``x = g(x)`` with ``T_peak = T_amb + k x``. In u = ln x the root of
        phi(u) = ln g(e^u) - u is bracketed by x -> 0 (g(0) > 0: phi > 0) and
        x = g(0) (phi <= 0 when g decreases, as it does for gas warmer than its
        background); the Illinois variant of regula falsi closes the bracket,
        each step one fixed-temperature pass over the pixels not yet within
        0.3 % of their root."""
        span = 1.0 / passes
        out, g0 = self._g(np.zeros(idx.size), kk, idx, fraction_part(progress, 0.0, span))
        out = inv.writable_copy(out)
        live: np.ndarray = np.flatnonzero((g0 > 0) & out.valid)
        ua: np.ndarray = np.full(live.size, math.log(1e-7))
        fa = np.log(g0[live]) - ua  # > 0
        ub = np.log(np.minimum(g0[live], 1.0))
        res, gb = self._g(np.exp(ub), kk, idx[live], fraction_part(progress, span, 2 * span))
        fb = np.log(np.maximum(gb, 1e-12)) - ub
        inv.scatter_results(out, res, live)
        # No bracket (g not decreasing there): keep the pass at x = g(0).
        keep = (fb < 0) & (np.abs(fb) > 3e-3)
        live, ua, fa, ub, fb = live[keep], ua[keep], fa[keep], ub[keep], fb[keep]
        side: np.ndarray = np.zeros(live.size, int)
        for step in range(passes - 2):
            if live.size == 0:
                break
            uc = (ua * fb - ub * fa) / (fb - fa)
            res, gc = self._g(
                np.exp(uc),
                kk,
                idx[live],
                fraction_part(progress, (2 + step) * span, (3 + step) * span),
            )
            fc = np.log(np.maximum(gc, 1e-12)) - uc
            inv.scatter_results(out, res, live)
            pos = fc > 0  # the root lies above uc: uc replaces the lower end
            # Illinois: an end kept twice in a row has its value halved.
            fa = np.where(pos, fc, np.where(side == -1, 0.5 * fa, fa))
            fb = np.where(~pos, fc, np.where(side == 1, 0.5 * fb, fb))
            ua = np.where(pos, uc, ua)
            ub = np.where(~pos, uc, ub)
            side = np.where(pos, 1, -1)
            keep = np.abs(fc) > 3e-3
            live, ua, fa, ub, fb, side = (
                live[keep],
                ua[keep],
                fa[keep],
                ub[keep],
                fb[keep],
                side[keep],
            )
        return out
