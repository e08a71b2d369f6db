"""The flux integral across a control surface: emission rates from column
densities and normal velocities (thesis eq. 12), computed by the engine
(``engine/flux/surface_flux.h``, the same function C++ users call).

For each frame t, with the surface sampled at points i of segment length
``dl_i`` [m]::

    rate_t = sum_i c_ti v_ti dl_i                   [kg/s]
    var_t  = sum_i (v_ti sigma_ti dl_i)^2           [(kg/s)^2]

``c`` the column density of one species [kg/m2] (or [mol/m2] with its molar
mass given), ``sigma`` its 1-sigma, ``v`` the gas velocity along the
surface's normal [m/s] (positive: along the normal, i.e. out of the source's
side for a surface drawn around it). ``var_t`` is the columns' random term
of the rate's uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Optional

import numpy as np
from numpy.typing import ArrayLike

from .. import _engine

__all__ = ["SurfaceRate", "surface_rate"]


@dataclass
class SurfaceRate:
    """A surface's emission rate series (:func:`surface_rate`).

    Attributes
    ----------
    rate : ndarray (frames,)
        Emission rate through the surface [kg/s] per frame. Samples without a
        finite column count as no gas; NaN for a frame with no finite column
        or where a finite column meets a non-finite velocity.
    samples : ndarray (frames,) int
        Samples with a finite column per frame.
    rate_variance : ndarray (frames,)
        The columns' random term of the rate's variance per frame,
        ``sum (v_n sigma_c dl)^2`` [(kg/s)^2] (non-finite velocities count as 0).
    """

    rate: np.ndarray
    samples: np.ndarray
    rate_variance: np.ndarray

    @property
    def column_variance(self) -> float:
        """``rate_variance`` summed over the frames [(kg/s)^2]."""
        return float(np.sum(self.rate_variance))


def surface_rate(
    column: ArrayLike,
    column_sigma: Optional[ArrayLike],
    normal_velocity: ArrayLike,
    length_m: ArrayLike,
    molar_mass_kg_mol: Optional[float] = None,
) -> SurfaceRate:
    """Emission rate of one species through a surface, frame by frame.

    Parameters
    ----------
    column : array (frames, samples)
        Column density at the surface's sample points [kg/m2], or [mol/m2]
        when ``molar_mass_kg_mol`` is given; NaN where not measured.
    column_sigma : array (frames, samples) or None
        1-sigma of ``column`` in its unit; None: no column term (zeros).
    normal_velocity : array broadcastable to (frames, samples)
        Gas velocity along the surface normal at the samples [m/s].
    length_m : array (samples,)
        Length of the surface segment of each sample [m].
    molar_mass_kg_mol : float, optional
        Molar mass of the species [kg/mol] for molar columns (e.g.
        ``qogi._engine.molar_mass("CH4")``); None: mass columns.

    Returns
    -------
    SurfaceRate
    """
    c = np.asarray(column, dtype=float)
    if c.ndim != 2:
        raise ValueError(f"column must be a (frames, samples) array; got shape {c.shape}")
    try:
        vn = np.broadcast_to(np.asarray(normal_velocity, dtype=float), c.shape)
    except ValueError:
        raise ValueError(
            f"normal_velocity must be broadcastable to the column's shape {c.shape}; "
            f"got {np.shape(normal_velocity)}"
        ) from None
    sig = np.zeros(c.shape) if column_sigma is None else np.asarray(column_sigma, dtype=float)
    if sig.shape != c.shape:
        raise ValueError(f"column_sigma must have the column's shape {c.shape}; got {sig.shape}")
    dl = np.asarray(length_m, dtype=float)
    if dl.shape != (c.shape[1],):
        raise ValueError(
            f"length_m must hold one length [m] per sample ({c.shape[1]}); got shape {dl.shape}"
        )
    mm = 0.0 if molar_mass_kg_mol is None else float(molar_mass_kg_mol)
    if molar_mass_kg_mol is not None and not (np.isfinite(mm) and mm > 0):
        raise ValueError(
            f"molar_mass_kg_mol must be finite and > 0 [kg/mol]; got {molar_mass_kg_mol}"
        )
    rate, samples, var = _engine.surface_flux_rate(c, sig, np.ascontiguousarray(vn), dl, mm)
    return SurfaceRate(rate, samples, var)
