"""The inversion API on synthetic line tables (fast): recovery of known
plumes, every status, image shapes and masks, both orders of time averaging,
the plume depth from its width, and bad input. The HITRAN round trip and the
thesis's gas-temperature finding are in test_inversion_hitran.py."""

import numpy as np
import pytest
from synthetic_tables import lorentz_table

import qogi
from qogi.measure.inversion import (
    AT_BOUND,
    BELOW_DETECTION,
    CONVERGED,
    FAILED,
    MASKED,
    fixed,
    free,
    plume_depth_from_width,
    prior,
    tied,
)

T_AMB = 293.0
NETD = 0.017


@pytest.fixture(scope="module")
def model():
    # "CH4" lines at 2950-3100 cm-1, "CO2" lines at 2150-2300 cm-1: spectrally
    # separate, as the real bands are, seen by four channels.
    chans = [
        qogi.SpectralResponse([2130.0, 2140.0, 3110.0, 3120.0], [0, 0.8, 0.8, 0], "open"),
        qogi.SpectralResponse([2140.0, 2150.0, 2300.0, 2310.0], [0, 0.8, 0.8, 0], "co2"),
        qogi.SpectralResponse([2950.0, 2960.0, 3090.0, 3100.0], [0, 0.8, 0.8, 0], "ch4"),
        qogi.SpectralResponse([2980.0, 2990.0, 3030.0, 3040.0], [0, 0.8, 0.8, 0], "ch4 n"),
    ]
    tables = [
        lorentz_table("CH4", 2930.0, 3120.0, seed=1, n_lines=80),
        lorentz_table("CO2", 2130.0, 2320.0, seed=2, n_lines=80),
    ]
    return qogi.ForwardModel(
        chans,
        ["CH4", "CO2"],
        tables=tables,
        fast_options=qogi._engine.BinnedModelOptions(num_nodes=65),
    )


@pytest.fixture(scope="module")
def inversion(model):
    # Both fractions free, the gas temperature known per pixel, sigma given.
    return qogi.Inversion(
        model,
        T_AMB,
        netd_K=NETD,
        temperature=fixed(320.0),
        temperature_range_K=(290.0, 360.0),
        max_sigma_m=1.0,
    )


def plumes(model, n, seed):
    rng = np.random.default_rng(seed)
    x = np.stack([10 ** rng.uniform(-3, -1, n), 10 ** rng.uniform(-3, -1, n)], axis=1)
    tp = rng.uniform(300.0, 355.0, n)
    sg = rng.uniform(0.02, 0.1, n)
    tb = np.full(n, T_AMB - 15.0)
    rad = model.band_radiance(x, tp, sg, T_AMB, tb[:, None].repeat(4, 1))
    return x, tp, sg, tb, rad.T


def test_recovers_known_plumes_and_reports_uncertainty(model, inversion):
    x, tp, sg, tb, rad = plumes(model, 30, 1)
    res = inversion.invert(
        rad, background_temperature_K=np.repeat(tb[None], 4, 0), sigma_m=sg, peak_temperature_K=tp
    )
    assert np.all(res.status == CONVERGED)
    col = model.column_density(x, tp, sg, T_AMB)
    for s in ("CH4", "CO2"):
        # Only the table's interpolation error remains without noise.
        np.testing.assert_allclose(res.column_density[s], col[s], rtol=5e-3)
        assert np.all(res.column_density_sigma[s] > 0)
        # ppm m = 1e6 sqrt(2 pi) x sigma.
        np.testing.assert_allclose(
            res.path_concentration_ppm_m[s],
            1e6 * np.sqrt(2 * np.pi) * res.peak_fraction[s] * sg,
            rtol=1e-12,
        )
    np.testing.assert_allclose(res.peak_temperature_K, tp)
    np.testing.assert_allclose(res.sigma_m, sg)
    assert np.all(res.chi2 < 1e-2)
    assert res.covariance.shape == (30, 4, 4)


def test_uncertainty_matches_the_scatter_of_noisy_repeats(model, inversion):
    # One plume, 400 noise draws: the spread of the estimates equals the
    # reported sigma (the covariance is honest when the noise model is right).
    x, tp, sg, tb, rad = plumes(model, 1, 2)
    noise = inversion.channel_noise(tb[0])
    rng = np.random.default_rng(3)
    n = 400
    rr = rad + rng.standard_normal((4, n)) * noise[:, None]
    res = inversion.invert(
        rr,
        background_temperature_K=np.full((4, n), tb[0]),
        sigma_m=np.full(n, sg[0]),
        peak_temperature_K=np.full(n, tp[0]),
    )
    assert np.all(res.valid)
    for s in ("CH4", "CO2"):
        spread = np.std(res.column_density[s])
        reported = np.median(res.column_density_sigma[s])
        assert spread / reported == pytest.approx(1.0, abs=0.12)


def test_every_status(model, inversion):
    tb = T_AMB - 15.0
    bg = model.background_radiance(tb)
    warm = model.band_radiance({"CH4": 0.05, "CO2": 0.05}, 320.0, 0.05, T_AMB, tb)
    no_co2 = model.band_radiance({"CH4": 0.05, "CO2": 0.0}, 320.0, 0.05, T_AMB, tb)
    rad = np.stack([bg, warm, no_co2, warm, bg - 0.5 * (warm - bg), warm], axis=1)
    rad[2, 3] = np.nan  # a dead pixel
    bgt = np.full((4, 6), tb)
    bgt[:, 5] = 100.0  # a background temperature outside the tables
    mask = np.array([True, True, True, True, True, True])
    res = inversion.invert(
        rad, background_temperature_K=bgt, sigma_m=0.05, peak_temperature_K=320.0, mask=mask
    )
    assert res.status[0] == BELOW_DETECTION  # no contrast: not inverted
    assert res.column_density["CH4"][0] == 0.0
    assert res.column_density_sigma["CH4"][0] > 0.0  # the noise-equivalent column
    assert res.status[1] == CONVERGED
    assert res.status[2] == AT_BOUND and res.bound_mask[2] == 0b10  # x_CO2 held at 0
    assert res.peak_fraction["CO2"][2] == 0.0
    assert res.status[3] == FAILED  # NaN input
    assert res.status[4] == AT_BOUND  # darker than the background: x held at 0
    assert res.status[5] == FAILED  # background outside the tables
    masked = inversion.invert(
        rad[:, :3],
        background_temperature_K=bgt[:, :3],
        sigma_m=0.05,
        peak_temperature_K=320.0,
        mask=np.array([True, False, True]),
    )
    assert masked.status[1] == MASKED
    assert masked.status[2] == res.status[2]
    for arr in (
        res.parameters,
        res.parameter_sigma,
        res.covariance,
        res.chi2,
        res.column_density["CH4"],
        res.column_density_sigma["CO2"],
    ):
        assert np.all(np.isfinite(arr))
    counts = res.counts()
    assert counts["failed"] == 2 and counts["at_bound"] == 2
    m = res.masked(res.column_density["CH4"])
    assert m.mask.tolist() == [True, False, False, True, False, True]


def test_images_with_radiance_backgrounds_and_warm_starts(model):
    # A smooth 2-D plume, channels x H x W; neighbour warm starts agree with
    # cold starts; the background given as radiance.
    h, w = 6, 9
    yy, xx = np.mgrid[0:h, 0:w]
    x = 0.05 * np.exp(-0.5 * ((xx - 4) / 2.0) ** 2) * (1 + 0.1 * yy)
    tb = T_AMB - 12.0
    rad = model.band_radiance(np.stack([x, 0.5 * x], -1), 330.0, 0.04, T_AMB, tb)
    rad = np.moveaxis(rad, -1, 0)
    bg = model.background_radiance(tb)
    results = []
    for guess in ("table", "neighbour"):
        inv = qogi.Inversion(
            model,
            T_AMB,
            netd_K=NETD,
            temperature=fixed(330.0),
            max_sigma_m=1.0,
            sigma_m=0.04,
            initial_guess=guess,
        )
        res = inv.invert(rad, background_radiance=bg)
        assert res.status.shape == (h, w) and res.parameters.shape == (h, w, 4)
        results.append(res)
    ok = results[0].valid
    assert ok.sum() > 0.8 * h * w
    np.testing.assert_allclose(
        results[1].column_density["CH4"][ok], results[0].column_density["CH4"][ok], rtol=1e-5
    )


def test_both_orders_of_averaging(model):
    # A column that fluctuates from frame to frame: the contrast is concave in
    # the column, so inverting the mean image reads low, while the mean of the
    # per-frame inversions is right (the thesis compares both orders).
    inv = qogi.Inversion(
        model,
        T_AMB,
        netd_K=NETD,
        fractions={"CH4": "free"},
        temperature=fixed(T_AMB),
        sigma_m=0.05,
        max_sigma_m=1.0,
    )
    rng = np.random.default_rng(4)
    t = 40
    x = 0.3 * rng.lognormal(0.0, 0.8, t)
    x = np.minimum(x, 1.0)
    tb = T_AMB - 15.0
    frames = model.band_radiance({"CH4": x[:, None]}, T_AMB, 0.05, T_AMB, tb)  # (T, 1, C)
    frames = np.moveaxis(frames, -1, 1)  # (T, C, 1)
    truth = model.column_density({"CH4": x}, T_AMB, 0.05, T_AMB)["CH4"].mean()
    per = inv.invert_frames(frames, background_temperature_K=tb)
    assert per.status.shape == (t, 1)
    mean_col, mean_sig, n = per.frame_mean("CH4")
    assert n[0] == t
    assert mean_col[0] == pytest.approx(truth, rel=0.01)
    avg = inv.invert_mean(frames, background_temperature_K=tb)
    assert avg.status[0] == CONVERGED
    assert avg.column_density["CH4"][0] < 0.9 * truth
    # The mean image's noise is NETD / sqrt(T).
    assert avg.info["noise_scale"] == pytest.approx(1 / np.sqrt(t))
    # Warm starts from the previous frame give the cold-start answers.
    cold = inv.invert_frames(frames, background_temperature_K=tb, warm_start=False)
    np.testing.assert_allclose(per.column_density["CH4"], cold.column_density["CH4"], rtol=1e-5)


def test_single_channel_newton_path(model):
    one = qogi.ForwardModel(
        [model.channels[2]],
        ["CH4"],
        tables=model.tables[:1],
        fast_options=qogi._engine.BinnedModelOptions(num_nodes=65),
    )
    inv = qogi.Inversion(one, T_AMB, netd_K=NETD, sigma_m=0.05, max_sigma_m=1.0)
    assert inv.temperature.mode == "fixed" and inv.temperature.value == T_AMB
    x = np.array([5e-3, 2e-2, 0.1, 0.5])
    tb = T_AMB - 10.0
    rad = one.band_radiance({"CH4": x}, T_AMB, 0.05, T_AMB, tb).T
    res = inv.invert(rad, background_temperature_K=tb)
    assert np.all(res.status == CONVERGED)
    np.testing.assert_allclose(res.peak_fraction["CH4"], x, rtol=3e-3)


def test_tied_composition_and_priors(model):
    inv = qogi.Inversion(
        model,
        T_AMB,
        netd_K=NETD,
        max_sigma_m=1.0,
        fractions={"CH4": free(), "CO2": tied("CH4", 0.5)},
        temperature=fixed(330.0),
        sigma_m=prior(0.05, 0.01),
    )
    tb = T_AMB - 15.0
    rad = model.band_radiance({"CH4": 0.04, "CO2": 0.02}, 330.0, 0.05, T_AMB, tb)
    res = inv.invert(rad, background_temperature_K=tb)
    assert res.status == CONVERGED
    assert res.peak_fraction["CO2"] == pytest.approx(0.5 * res.peak_fraction["CH4"], rel=1e-12)
    assert res.peak_fraction_sigma["CO2"] == pytest.approx(0.5 * res.peak_fraction_sigma["CH4"])
    col = model.column_density({"CH4": 0.04, "CO2": 0.02}, 330.0, 0.05, T_AMB)
    assert res.column_density["CH4"] == pytest.approx(col["CH4"], rel=0.01)
    assert 0 < res.sigma_sigma_m <= 0.01 + 1e-12  # no more uncertain than its prior


def test_profile_cold_start_finds_the_minima_of_exhaustive_starts(model):
    """With the temperature free, the default cold start (chi2 profiled over
    T_peak, its local minima polished) must fit every pixel as well as full
    solves started from every candidate of the coarse lookup, and flag the
    same pixels ambiguous (two minima within chi2 + 4)."""
    x, tp, sg, tb, rad = plumes(model, 150, 5)
    rng = np.random.default_rng(6)
    inv = {
        k: qogi.Inversion(
            model, T_AMB, netd_K=NETD, temperature=free(290.0, 360.0), max_sigma_m=1.0, cold_start=k
        )
        for k in ("profile", "starts")
    }
    noise = inv["profile"].channel_noise(tb[0])[:, None]
    rad = rad + rng.standard_normal(rad.shape) * noise
    r = {k: v.invert(rad, background_temperature_K=tb, sigma_m=sg) for k, v in inv.items()}
    ok = r["starts"].valid
    assert ok.sum() >= 140 and np.all(r["profile"].valid[ok])
    worse = r["profile"].chi2[ok] - r["starts"].chi2[ok]
    assert np.all(worse < 0.05), np.sort(worse)[-5:]
    amb = {k: (v.flags & 1).astype(bool) for k, v in r.items()}
    assert np.mean(amb["profile"][ok] == amb["starts"][ok]) > 0.95


def test_scene_tables_are_cached(model):
    a = qogi.measure.inversion.scene_table(
        model, T_AMB, min_peak_temperature_K=290.0, max_peak_temperature_K=310.0, max_sigma_m=1.0
    )
    b = qogi.measure.inversion.scene_table(
        model, T_AMB, min_peak_temperature_K=290.0, max_peak_temperature_K=310.0, max_sigma_m=1.0
    )
    assert a is b
    err = qogi._engine.measure_table_error(a, 40, 5)
    assert err["max_relative_error"] < 5e-3


def test_progress_and_cancel(model, inversion):
    x, tp, sg, tb, rad = plumes(model, 600, 5)
    seen = []
    inversion.invert(
        rad,
        background_temperature_K=np.repeat(tb[None], 4, 0),
        sigma_m=sg,
        peak_temperature_K=tp,
        progress=seen.append,
    )
    assert seen and seen[-1] == 1.0
    with pytest.raises(qogi.Cancelled):
        inversion.invert(
            rad,
            background_temperature_K=np.repeat(tb[None], 4, 0),
            sigma_m=sg,
            peak_temperature_K=tp,
            progress=lambda f: False,
        )


def test_plume_depth_from_width_recovers_the_sigma_of_a_sampled_gaussian_cut_at_20_percent():
    """Noise-free Gaussians of known sigma at 41 sub-pixel positions (and one
    near the profile's end, still held down to 20 % of its peak): the
    samples above the cut, their moment divided by the truncated Gaussian's
    0.69, give sigma within the error of the cut falling between samples:
    6.5 % at 1.5 px, 4.5 % at 3 px, 2 % at 6.5 px, 1.5 % at 12 px. The
    plain moment of the kept samples (no truncation correction) is > 10 %
    low (17 % for a finely sampled Gaussian)."""
    s = np.arange(64.0)
    for sigma_px, centre, tol in (
        (1.5, 30.0, 0.065),
        (3.0, 30.0, 0.045),
        (3.0, 6.0, 0.045),
        (6.5, 30.0, 0.02),
        (12.0, 31.0, 0.015),
    ):
        for d in np.linspace(0.0, 1.0, 41):
            prof = np.exp(-0.5 * ((s - centre - d) / sigma_px) ** 2)
            got = plume_depth_from_width(np.stack([prof, 2 * prof]), pixel_size_m=0.002)
            assert np.all(np.abs(got / (sigma_px * 0.002) - 1.0) < tol), (sigma_px, centre + d)
        kept = np.where(prof > 0.2, prof, 0.0)
        m = (kept * s).sum() / kept.sum()
        plain = np.sqrt((kept * (s - m) ** 2).sum() / kept.sum())
        assert plain / sigma_px < 0.9
    col = np.exp(-0.5 * ((s - 20.0) / 4.0) ** 2)[:, None] * np.ones((1, 3))
    np.testing.assert_allclose(plume_depth_from_width(col, 1.0, axis=0), 4.0, rtol=0.03)
    assert plume_depth_from_width(np.zeros((2, 5)), 0.01)[0] == 0.0
    with pytest.raises(ValueError, match="pixel_size_m"):
        plume_depth_from_width(prof, -1.0)
    with pytest.raises(ValueError, match="cut"):
        plume_depth_from_width(prof, 1.0, cut=1.0)


def test_plume_depth_from_width_of_noisy_profiles_is_unbiased_within_the_noise():
    """200 seeded profiles, Gaussian (sigma 6.5 px, peak 1) plus white noise of
    3 % of the peak: the mean depth is within 1 % of sigma (one profile
    scatters by ~2.5 %, the mean of 200 by ~0.2 %; the cut's discreteness
    ~0.8 %). Without the cut (every positive sample counts, a plain second
    moment) noise in the wings inflates the depth by > 10 %."""
    rng = np.random.default_rng(19)
    s = np.arange(64.0)
    prof = np.exp(-0.5 * ((s - 30.2) / 6.5) ** 2) + 0.03 * rng.standard_normal((200, 64))
    got = plume_depth_from_width(prof, pixel_size_m=1.0)
    assert abs(got.mean() / 6.5 - 1.0) < 0.01
    assert got.std() / 6.5 < 0.04
    assert plume_depth_from_width(prof, pixel_size_m=1.0, cut=0.0).mean() / 6.5 > 1.1


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(netd_K=-1.0), ["netd_K"]),
        (dict(netd_K=[0.01, 0.02]), ["netd_K", "per channel"]),
        (dict(fractions={"N2O": "free"}), ["N2O", "species"]),
        (dict(fractions={"CH4": "free", "CO2": tied("H2O", 1.0)}), ["H2O"]),
        (dict(fractions={"CH4": "wild"}), ["fractions['CH4']"]),
        (dict(temperature=fixed(900.0)), ["range"]),
        (
            dict(fractions={"CH4": 0.1, "CO2": 0.1}, temperature=fixed(300.0)),
            ["every parameter is fixed"],
        ),
        (dict(initial_guess="psychic"), ["initial_guess"]),
        (dict(solver="magic"), ["solver"]),
        (dict(cold_start="lucky"), ["cold_start"]),
    ],
)
def test_bad_settings(model, kwargs, words):
    args = dict(netd_K=NETD, max_sigma_m=1.0)
    args.update(kwargs)
    with pytest.raises(ValueError) as e:
        qogi.Inversion(model, T_AMB, **args)
    for w in words:
        assert w in str(e.value)


def test_bad_inputs(model, inversion):
    rad = np.ones((4, 3))
    with pytest.raises(ValueError, match="exactly one"):
        inversion.invert(rad)
    with pytest.raises(ValueError, match="exactly one"):
        inversion.invert(rad, background_radiance=rad, background_temperature_K=280.0)
    with pytest.raises(ValueError, match="C = 4 channels"):
        inversion.invert(np.ones((3, 3)), background_temperature_K=280.0)
    with pytest.raises(ValueError, match="mask"):
        inversion.invert(rad, background_temperature_K=280.0, mask=np.ones(4, bool))
    with pytest.raises(ValueError, match="sigma_m"):
        inversion.invert(rad, background_temperature_K=280.0, sigma_m=np.array([0.1, 5.0, 0.1]))
    with pytest.raises(ValueError, match="peak_temperature_K"):
        inversion.invert(rad, background_temperature_K=280.0, peak_temperature_K=500.0)
    with pytest.raises(ValueError, match="background_temperature_K"):
        inversion.invert(rad, background_temperature_K=np.ones((4, 5)))
    with pytest.raises(ValueError, match=r"\(T, C, ...\)"):
        inversion.invert_frames(np.ones(4), background_temperature_K=280.0)
