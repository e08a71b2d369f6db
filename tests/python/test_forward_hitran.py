"""The forward models on real HITRAN tables (the HITRAN subsets qogi ships), every preset
channel: physics limits, the thesis's Table 4, and the fast model against the
exact one over the issue's domain."""

import numpy as np
import pytest

import qogi

# Relative to the contrast, with a floor for near-cancelling contrasts:
# 1e-4 of the background radiance (about 2 mK at 3.3 um) is judged absolutely.
FLOOR = 1e-4


@pytest.fixture(scope="module")
def channels():
    return qogi.camera_preset("fast-m150").channels + qogi.camera_preset("gf320").channels


@pytest.fixture(scope="module")
def model(channels, hitran_dir):
    return qogi.ForwardModel(
        channels,
        ["CH4", "CO2"],
        line_lists={"CH4": hitran_dir / "CH4.par.gz", "CO2": hitran_dir / "CO2.par.gz"},
    )


def contrast_error(lf, le, bg):
    return np.abs(lf - le) / np.maximum(np.abs(le - bg), FLOOR * bg)


@pytest.mark.parametrize("exact", [False, True])
def test_zero_contrast_when_the_gas_is_at_the_background_temperature(model, exact):
    opts = qogi._engine.ExactModelOptions(num_nodes=41)
    m = qogi.ForwardModel(model.channels, model.species, tables=model.tables, exact_options=opts)
    for t in (270.0, 310.0):
        rad = m.band_radiance({"CH4": 0.5, "CO2": 0.5}, t, 0.1, t, t, exact=exact)
        np.testing.assert_allclose(rad, m.background_radiance(t), rtol=1e-9, atol=0)


def test_white_plume_black_plume_every_gas_channel(model):
    bg = model.background_radiance(290.0)
    warm = model.band_radiance({"CH4": 0.05, "CO2": 0.05}, 330.0, 0.05, 300.0, 290.0)
    cold = model.band_radiance({"CH4": 0.05, "CO2": 0.05}, 270.0, 0.05, 270.0, 290.0)
    # The CO2 channel (index 1) sees CO2; the others see CH4; all see something.
    assert np.all(warm > bg) and np.all(cold < bg)


def test_thin_limit_is_linear_in_column(model):
    x = np.array([1e-7, 2e-7])
    rad = model.band_radiance({"CH4": x, "CO2": x}, 320.0, 0.05, 300.0, 290.0)
    c = rad - model.background_radiance(290.0)
    np.testing.assert_allclose(c[1] / c[0], 2.0, rtol=1e-4)


def test_contrast_saturates_monotonically(model):
    x = np.geomspace(1e-6, 1.0, 13)
    c = model.band_radiance({"CH4": x}, 320.0, 0.2, 320.0, 290.0) - model.background_radiance(290.0)
    gas = [0, 2, 3, 4]  # channels that see CH4
    assert np.all(np.diff(c[:, gas], axis=0) > 0)
    # The increments shrink: saturation.
    d = np.diff(np.log(c[:, 4]))
    assert d[-1] < 0.5 * d[0]


def test_fast_model_agrees_with_exact_over_the_domain(model, capsys):
    rng = np.random.default_rng(20261122)
    worst_c = np.zeros(len(model.channels))
    worst_l = np.zeros(len(model.channels))
    cases = []
    for k in range(8):
        ta = rng.uniform(250, 320)
        tp = ta + rng.uniform(-30, 200)
        which = k % 3  # CH4 alone, CO2 alone, mixed
        x1 = 10 ** rng.uniform(-5, 0) if which != 1 else 0.0
        x2 = (1 - x1) * 10 ** rng.uniform(-5, 0) if which != 0 else 0.0
        cases.append((x1, x2, tp, 10 ** rng.uniform(-3, np.log10(0.5)), ta, rng.uniform(250, 350)))
    # Corners: thickest, hottest, coldest.
    cases += [(1.0, 0.0, 520.0, 0.5, 320.0, 250.0), (0.5, 0.5, 220.0, 0.001, 250.0, 350.0)]
    for x1, x2, tp, sg, ta, tb in cases:
        le = model.band_radiance({"CH4": x1, "CO2": x2}, tp, sg, ta, tb, exact=True)
        lf = model.band_radiance({"CH4": x1, "CO2": x2}, tp, sg, ta, tb)
        bg = model.background_radiance(tb)
        worst_c = np.maximum(worst_c, contrast_error(lf, le, bg))
        worst_l = np.maximum(worst_l, np.abs(lf / le - 1))
    with capsys.disabled():
        print(
            f"\nfast vs exact, {len(cases)} plumes, channels "
            f"{[c.name for c in model.channels]}:\n  worst contrast error "
            f"{np.array2string(worst_c, precision=4)}\n  worst L error "
            f"{np.array2string(worst_l, precision=5)}"
        )
    assert np.all(worst_c < 0.01)
    assert np.all(worst_l < 0.003)
