"""The forward-model API on synthetic line tables (HITRAN-based checks live in
test_forward_hitran.py)."""

import numpy as np
import pytest
from synthetic_tables import lorentz_table

import qogi

KB, NA = 1.380649e-23, 6.02214076e23


@pytest.fixture(scope="module")
def model():
    chans = [
        qogi.SpectralResponse([2950.0, 2960.0, 3090.0, 3100.0], [0, 0.8, 0.8, 0], "A"),
        qogi.SpectralResponse([2985.0, 2990.0, 3030.0, 3035.0], [0, 0.8, 0.8, 0], "B"),
    ]
    tables = [lorentz_table("CH4", seed=1), lorentz_table("CO2", seed=2, with_self=False)]
    return qogi.ForwardModel(
        chans,
        ["CH4", "CO2"],
        tables=tables,
        exact_options=qogi._engine.ExactModelOptions(num_nodes=201),
    )


@pytest.mark.parametrize("exact", [False, True])
def test_zero_contrast_when_the_whole_path_is_at_the_background_temperature(model, exact):
    for t in (260.0, 300.0, 340.0):
        rad = model.band_radiance({"CH4": 0.4, "CO2": 0.3}, t, 0.05, t, t, exact=exact)
        np.testing.assert_allclose(rad, model.background_radiance(t), rtol=1e-9)


def test_white_plume_when_warmer_black_plume_when_colder(model):
    bg = model.background_radiance(290.0)
    assert np.all(model.band_radiance({"CH4": 0.1}, 320.0, 0.05, 300.0, 290.0) > bg)
    assert np.all(model.band_radiance({"CH4": 0.1}, 280.0, 0.05, 280.0, 290.0) < bg)


def test_batches_broadcast_and_per_channel_backgrounds(model):
    x = np.array([1e-3, 1e-2, 1e-1])
    batch = model.band_radiance({"CH4": x}, 320.0, 0.05, 300.0, 290.0)
    assert batch.shape == (3, 2)
    one = model.band_radiance({"CH4": 1e-2}, 320.0, 0.05, 300.0, 290.0)
    np.testing.assert_allclose(batch[1], one, rtol=1e-12)
    # Contrast grows with column.
    assert np.all(np.diff(batch[:, 0]) > 0)
    per = model.band_radiance({"CH4": 1e-2}, 320.0, 0.05, 300.0, [290.0, 280.0])
    np.testing.assert_allclose(per[0], one[0], rtol=1e-12)
    assert per[1] != one[1]


def test_fast_agrees_with_exact(model):
    rng = np.random.default_rng(3)
    worst = 0.0
    for _ in range(6):
        ta = rng.uniform(250, 320)
        tp = ta + rng.uniform(-30, 200)
        x = 10 ** rng.uniform(-4, -0.5)
        sg, tb = 10 ** rng.uniform(-3, -0.5), rng.uniform(250, 350)
        le = model.band_radiance({"CH4": x}, tp, sg, ta, tb, exact=True)
        lf = model.band_radiance({"CH4": x}, tp, sg, ta, tb)
        bg = model.background_radiance(tb)
        worst = max(worst, np.max(np.abs(lf - le) / np.maximum(np.abs(le - bg), 1e-4 * bg)))
    assert worst < 0.01


def test_column_density_is_eq6():
    c = qogi.column_density({"CH4": 0.25, "CO2": 0.5}, 300.0, 0.04, 300.0)
    n = 101325.0 / (KB * 300.0)
    assert c["CH4"] == pytest.approx(
        16.0425e-3 / NA * 0.25 * n * 0.04 * np.sqrt(2 * np.pi), rel=1e-12
    )
    # Hotter core: fewer molecules for the same fractions.
    hot = qogi.column_density({"CH4": 0.25}, 400.0, 0.04, 300.0)
    assert hot["CH4"] < c["CH4"]
    arr = qogi.column_density({"CH4": np.array([0.1, 0.2])}, 300.0, 0.04, 300.0)
    np.testing.assert_allclose(arr["CH4"][1] / arr["CH4"][0], 2.0)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(species={"XYZ": 0.1}), ["unknown species", "XYZ"]),
        (dict(sigma_m=-1.0), ["sigma_m", "> 0"]),
        (dict(species={"CH4": 1.5}), ["[0, 1]"]),
    ],
)
def test_column_density_rejects_bad_input(kwargs, words):
    args = dict(
        species={"CH4": 0.1}, peak_temperature_K=300.0, sigma_m=0.05, ambient_temperature_K=300.0
    )
    args.update(kwargs)
    with pytest.raises(ValueError) as e:
        qogi.column_density(**args)
    for w in words:
        assert w in str(e.value)


def test_model_rejects_bad_plumes(model):
    with pytest.raises(ValueError, match="sum to"):
        model.band_radiance({"CH4": 0.7, "CO2": 0.6}, 300.0, 0.05, 300.0, 290.0)
    with pytest.raises(ValueError, match="outside the tables' range"):
        model.band_radiance({"CH4": 0.1}, 900.0, 0.05, 300.0, 290.0)
    with pytest.raises(ValueError, match="species"):
        model.band_radiance({"N2O": 0.1}, 300.0, 0.05, 300.0, 290.0)


def test_camera_presets():
    assert set(qogi.camera_preset_names()) >= {"gf320", "fast-m150"}
    gf = qogi.camera_preset("gf320")
    assert (gf.width, gf.height, gf.frame_rate_hz, gf.netd_K) == (320, 240, 15.0, 0.015)
    assert gf.ifov_rad * 320 == pytest.approx(np.radians(24.0))
    m150 = qogi.camera_preset("fast-m150")
    assert len(m150.channels) == 4 and m150.frame_rate_hz == 100.0
    # Thesis Table 4: 288.7 K over 1852-6667 cm-1 = 2.09 W/(m2 sr) without the
    # lens, less through the open channel (lens x detector).
    assert qogi.SpectralResponse([1852.0, 6667.0], [1.0, 1.0]).band_radiance(
        288.7
    ) == pytest.approx(2.09, abs=0.005)
    assert m150.channels[0].band_radiance(288.7) < 2.09
    with pytest.raises(ValueError, match="gf320"):
        qogi.camera_preset("nope")
