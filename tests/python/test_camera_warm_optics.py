"""Warm filter and lens emission (thesis section 4.3.3) against physics."""

from __future__ import annotations

import numpy as np
import pytest

import qogi
from qogi.physics.camera import (
    ChannelOptics,
    add_warm_optics,
    camera_optics,
    correct_warm_optics,
    warm_optics_radiance,
)

NU = np.arange(1800.0, 6700.0 + 0.5, 1.0)


def det(nu):
    return 1.0 / (1.0 + np.exp(-(nu - 1900.0) / 15.0))


def tau_f(nu):
    return 0.8 / (1.0 + np.exp(-(nu - 2250.0) / 8.0)) / (1.0 + np.exp((nu - 2380.0) / 8.0))


def rho_f(nu):
    return 0.9 * (1.0 - tau_f(nu) / 0.8)


def tau_l(nu):
    return 0.92 - 0.1 * ((nu - 3500.0) / 2000.0) ** 2


def integral(f):
    """Reference: trapezoid of the analytic integrand on a 0.05 cm-1 grid."""
    x = np.linspace(1800.0, 6700.0, 98001)
    return np.trapezoid(f(x), x)


def planck(x, t):
    return qogi.planck_radiance(x, t)


def optics(reflective=True):
    return ChannelOptics(
        NU, det(NU), tau_f(NU), tau_l(NU), rho_f(NU) if reflective else None, name="test"
    )


def test_vanishes_for_a_perfectly_transmitting_filter_and_lens():
    one = np.ones_like(NU)
    clear = ChannelOptics(NU, det(NU), one, tau_l(NU))
    assert clear.filter_term(300.0) == 0.0
    ref = integral(lambda x: det(x) * (1 - tau_l(x)) * planck(x, 300.0))
    assert clear.warm_radiance(300.0, 300.0) == pytest.approx(ref, rel=1e-5)  # lens only
    perfect = ChannelOptics(NU, det(NU), one, one)
    assert perfect.warm_radiance(300.0, 330.0, 300.0) == 0.0
    np.testing.assert_array_equal(perfect.warm_radiance([280.0, 300.0], 310.0), [0.0, 0.0])


@pytest.mark.parametrize("t_filter", [260.0, 293.15, 330.0])
def test_opaque_filter_emits_the_blackbody_band_radiance_through_d_times_emissivity(t_filter):
    opaque = ChannelOptics(NU, det(NU), np.full_like(NU, 1e-9), tau_l(NU), rho_f(NU))
    eps = 1.0 - 1e-9 - rho_f(NU)
    through = qogi.SpectralResponse(NU, det(NU) * eps).band_radiance(t_filter)
    ref = integral(lambda x: det(x) * (1 - rho_f(x)) * planck(x, t_filter))
    for t_lens in (200.0, 350.0):  # (almost) nothing passes the filter:
        w = opaque.warm_radiance(t_lens, t_filter)
        # the lens adds 1e-9 x its band radiance (< 3 W/(m2 sr)) at most.
        assert w == pytest.approx(through, abs=3e-9)
        assert w == pytest.approx(ref, rel=5e-6)


def test_terms_against_independent_integrals():
    o = optics()
    tl, tf, tr = 296.0, 303.0, 280.0
    lens = integral(lambda x: det(x) * tau_f(x) * (1 - tau_l(x)) * planck(x, tl))
    filt = integral(lambda x: det(x) * (1 - tau_f(x) - rho_f(x)) * planck(x, tf))
    refl = integral(lambda x: det(x) * rho_f(x) * planck(x, tr))
    assert o.warm_radiance(tl, tf, tr) == pytest.approx(lens + filt + refl, rel=1e-5)
    assert o.warm_radiance(tl, tf) == pytest.approx(lens + filt, rel=1e-5)
    h = 0.01
    assert o.warm_radiance_derivative_filter(tf) == pytest.approx(
        (o.filter_term(tf + h) - o.filter_term(tf - h)) / (2 * h), rel=1e-6
    )
    assert o.warm_radiance_derivative_lens(tl) == pytest.approx(
        (o.lens_term(tl + h) - o.lens_term(tl - h)) / (2 * h), rel=1e-6
    )
    # The response is d tau_f tau_l.
    np.testing.assert_allclose(o.response.response, det(NU) * tau_f(NU) * tau_l(NU), rtol=1e-15)


@pytest.mark.parametrize("reflective", [False, True])
def test_closed_isothermal_system_is_a_blackbody_through_the_detector(reflective):
    o = optics(reflective)
    for t in (250.0, 293.15, 350.0):
        total = o.measured(o.response.band_radiance(t), t, t, t)
        assert total == pytest.approx(o.detector_band_radiance(t), rel=1e-12)
        assert total == pytest.approx(integral(lambda x, t=t: det(x) * planck(x, t)), rel=1e-5)


def test_preset_channels_obey_kirchhoff_too():
    for o in camera_optics("fast-m150") + camera_optics("gf320"):
        t = 300.0
        total = o.response.band_radiance(t) + o.warm_radiance(t, t)
        ref = np.trapezoid(o.detector_response * planck(o.nu_cm1, t), o.nu_cm1)
        assert total == pytest.approx(ref, rel=1e-5), o.name


def test_correction_is_the_exact_inverse_on_frame_stacks():
    opt = camera_optics("fast-m150")
    rng = np.random.default_rng(0)
    lum = rng.uniform(0.05, 2.0, (5, 4, 6, 7))
    t_lens = np.linspace(290.0, 300.0, 5)  # one per frame
    t_filter = t_lens + 1.0
    meas = add_warm_optics(lum, opt, t_lens, t_filter)
    w = warm_optics_radiance(opt, t_lens, t_filter)  # (5, 4)
    assert w.shape == (5, 4)
    np.testing.assert_array_equal(meas, lum + w[:, :, None, None])
    np.testing.assert_allclose(
        correct_warm_optics(meas, opt, t_lens, t_filter), lum, rtol=0, atol=1e-15
    )
    # Band-radiance vectors (channel on the last axis), as a forward model returns them.
    vec = lum[0, :, 0, 0]
    out = add_warm_optics(vec, opt, 293.15, 293.15, axis=-1)
    np.testing.assert_allclose(out - vec, warm_optics_radiance(opt, 293.15, 293.15), rtol=1e-15)
    # float32 stays float32.
    assert add_warm_optics(lum.astype(np.float32), opt, 293.0, 293.0).dtype == np.float32


def test_correction_relative_to_the_calibration_temperature():
    opt = camera_optics("fast-m150")
    lum = np.array([2.0, 0.15, 0.1, 0.5])
    # Calibrated with the optics at 20 C: the offset holds W(293.15 K).
    meas = add_warm_optics(lum, opt, 296.0, 297.0, axis=-1) - warm_optics_radiance(
        opt, 293.15, 293.15
    )
    got = correct_warm_optics(
        meas,
        opt,
        296.0,
        297.0,
        reference_lens_temperature_K=293.15,
        reference_filter_temperature_K=293.15,
        axis=-1,
    )
    np.testing.assert_allclose(got, lum, rtol=1e-13)
    with pytest.raises(ValueError, match="reference"):
        correct_warm_optics(meas, opt, 296.0, 297.0, reference_lens_temperature_K=293.15, axis=-1)


def test_warm_optics_grow_with_temperature_and_the_open_channel_has_no_filter_term():
    open_, co2 = camera_optics("fast-m150")[:2]
    w = co2.warm_radiance(np.arange(273.0, 324.0, 5.0), np.arange(273.0, 324.0, 5.0))
    assert np.all(np.diff(w) > 0)
    assert open_.filter_term(300.0) == 0.0 and open_.lens_term(300.0) > 0.0


def test_bad_optics_input():
    nu = np.array([2000.0, 3000.0])
    with pytest.raises(ValueError, match="filter_transmittance"):
        ChannelOptics(nu, [1, 1], [1.2, 1], [1, 1])
    with pytest.raises(ValueError, match="<= 1"):
        ChannelOptics(nu, [1, 1], [0.5, 0.5], [1, 1], [0.6, 0.2])
    with pytest.raises(ValueError, match="same length"):
        ChannelOptics(nu, [1], [0.5, 0.5], [1, 1])
    o = ChannelOptics(nu, [1, 1], [0.5, 0.5], [0.9, 0.9])
    with pytest.raises(ValueError, match="lens_temperature_K"):
        o.warm_radiance(-1.0, 300.0)
    with pytest.raises(ValueError, match="4 optics"):
        add_warm_optics(np.zeros((2, 3, 4, 4)), camera_optics("fast-m150"), 293.0, 293.0)
    with pytest.raises(ValueError, match=r"no optics breakdown|unknown camera preset"):
        camera_optics("gf999")


@pytest.mark.parametrize("name", ["gf320", "fast-m150"])
def test_preset_optics_reproduce_the_preset_channels(name):
    cam = qogi.camera_preset(name)
    opt = camera_optics(name)
    assert [o.name for o in opt] == [ch.name for ch in cam.channels]
    for o, ch in zip(opt, cam.channels):
        np.testing.assert_allclose(o.response.evaluate(ch.nu_cm1), ch.response, rtol=0, atol=1e-14)


def test_composes_with_the_forward_model():
    """Forward model + warm optics: a closed isothermal chain (gas, background,
    lens, filter) is the detector-band blackbody; the warm term cancels in the
    plume contrast and the correction recovers the forward model's radiance."""
    from synthetic_tables import lorentz_table

    nu = np.arange(2950.0, 3100.0 + 0.25, 0.5)
    band = 0.85 / (1 + np.exp(-(nu - 2990.0) / 3.0)) / (1 + np.exp((nu - 3060.0) / 3.0))
    opt = [
        ChannelOptics(
            nu, np.ones_like(nu), band, np.full_like(nu, 0.9), 0.5 * (1 - band), name="CH4 test"
        )
    ]
    model = qogi.ForwardModel(
        [o.response for o in opt], ["CH4"], tables=[lorentz_table("CH4", seed=3)]
    )
    for t in (280.0, 300.0):
        lum = model.band_radiance({"CH4": 0.3}, t, 0.05, t, t)
        total = add_warm_optics(lum, opt, t, t, t, axis=-1)
        assert total[0] == pytest.approx(opt[0].detector_band_radiance(t), rel=1e-9)
    plume = model.band_radiance({"CH4": 0.3}, 330.0, 0.05, 295.0, 288.15)
    bg = model.background_radiance(288.15)
    meas = add_warm_optics(plume, opt, 296.0, 297.0, axis=-1)
    meas_bg = add_warm_optics(bg, opt, 296.0, 297.0, axis=-1)
    assert meas[0] - meas_bg[0] == pytest.approx(plume[0] - bg[0], rel=1e-9)
    np.testing.assert_allclose(
        correct_warm_optics(meas, opt, 296.0, 297.0, axis=-1), plume, rtol=1e-13
    )
