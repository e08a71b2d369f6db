"""Synthetic absorption tables (Lorentz lines) for forward-model tests that
must not depend on HITRAN: the checks are then about radiative transfer only."""

import numpy as np

from qogi import _engine


def lorentz_table(
    species="CH4",
    nu0=2940.0,
    nu1=3110.0,
    dnu=0.02,
    seed=1,
    with_self=True,
    temperatures=None,
    n_lines=200,
):
    if temperatures is None:
        temperatures = np.arange(200.0, 600.0 + 1e-9, 25.0)
    rng = np.random.default_rng(seed)
    nu = nu0 + dnu * np.arange(int(round((nu1 - nu0) / dnu)) + 1)
    centres = rng.uniform(nu0 + 5, nu1 - 5, n_lines)
    s296 = 2e-19 * 10 ** (-4 * rng.uniform(size=n_lines))
    elower = 2000 * rng.uniform(size=n_lines)
    c2 = 1.438776877
    air = np.zeros((len(temperatures), len(nu)), np.float32)
    slf = np.zeros_like(air)
    for k, t in enumerate(temperatures):
        s = s296 * (296 / t) ** 1.5 * np.exp(-c2 * elower * (1 / t - 1 / 296))
        ga, gs = 0.06 * (296 / t) ** 0.75, 0.08 * (296 / t) ** 0.75
        d = nu[None, :] - centres[:, None]
        air[k] = (s[:, None] * ga / np.pi / (d * d + ga * ga)).sum(0)
        slf[k] = (s[:, None] * gs / np.pi / (d * d + gs * gs)).sum(0)
    return _engine.AbsorberTable(
        species,
        101325.0,
        nu0,
        dnu,
        np.asarray(temperatures, float),
        air,
        slf if with_self else None,
    )
