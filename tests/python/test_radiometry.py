"""The temperature <-> band radiance tables against the exact engine calls."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi.physics.radiometry import (
    BandTable,
    band_table,
    radiance_to_temperature,
    temperature_to_radiance,
)


def bands():
    nu = np.arange(2850.0, 3200.0, 1.0)
    return [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], "3.2-3.4 um"),
        qogi.SpectralResponse([1852.0, 6667.0], [1.0, 1.0], "InSb 1.5-5.4 um"),
        qogi.SpectralResponse.from_wavelength_um([7.5, 13.0], [1.0, 1.0], "LWIR"),
        qogi.SpectralResponse(nu, np.exp(-(((nu - 3030.0) / 70.0) ** 8)), "smooth filter"),
    ]


@pytest.mark.parametrize("ch", bands(), ids=lambda c: c.name)
def test_tables_match_the_exact_engine(ch):
    rng = np.random.default_rng(3)
    t = np.concatenate([rng.uniform(150.0, 1500.0, 4000), np.linspace(150.0, 1500.0, 501)])
    table = BandTable(ch)
    exact_l = ch.band_radiance(t)
    assert np.max(np.abs(table.radiance(t) / exact_l - 1.0)) < 1e-9
    assert np.max(np.abs(table.temperature(exact_l) - t)) < 1e-7


def test_values_outside_the_table_use_the_exact_engine():
    ch = bands()[0]
    table = BandTable(ch, t_min_K=250.0, t_max_K=400.0, nodes=64)
    t = np.array([60.0, 249.0, 401.0, 2000.0])
    np.testing.assert_allclose(table.radiance(t), ch.band_radiance(t), rtol=1e-12)
    np.testing.assert_allclose(table.temperature(ch.band_radiance(t)), t, rtol=1e-9)


def test_nan_passes_through_and_impossible_radiance_raises():
    table = band_table(bands()[0])
    out = table.radiance(np.array([300.0, np.nan]))
    assert np.isfinite(out[0]) and np.isnan(out[1])
    with pytest.raises(ValueError):
        table.temperature(np.array([-1.0]))


def test_frame_conversion_round_trip_keeps_float32_and_shape():
    chs = bands()
    rng = np.random.default_rng(0)
    f = rng.uniform(250.0, 350.0, (2, 4, 16, 20)).astype(np.float32)
    lum = temperature_to_radiance(f, chs)
    assert lum.dtype == np.float32 and lum.shape == f.shape
    for k, ch in enumerate(chs):
        np.testing.assert_allclose(lum[:, k], ch.band_radiance(f[:, k].astype(float)), rtol=2e-7)
    back = radiance_to_temperature(lum, chs)
    np.testing.assert_allclose(back, f, atol=1e-4)
    with pytest.raises(ValueError, match="3 channel responses"):
        temperature_to_radiance(f, chs[:3])
