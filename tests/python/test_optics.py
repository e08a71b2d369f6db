"""Planck and band radiance from Python, checked against analytic physics."""

import math
import pickle

import numpy as np
import pytest

import qogi

SIGMA_SB = 5.670374419e-8


def test_planck_broadcasts_and_matches_formula():
    nu = np.array([1000.0, 2000.0, 3000.0])
    t = np.array([[250.0], [300.0]])
    b = qogi.planck_radiance(nu, t)
    assert b.shape == (2, 3)
    h, c, k = 6.62607015e-34, 299792458.0, 1.380649e-23  # CODATA 2018, exact
    c1, c2 = 2 * h * c**2 * 1e8, 100 * h * c / k
    np.testing.assert_allclose(b, c1 * nu**3 / np.expm1(c2 * nu / t), rtol=1e-9)
    assert isinstance(qogi.planck_radiance(3000.0, 300.0), float)


@pytest.mark.parametrize("temperature", [250.0, 500.0, 1200.0])
def test_stefan_boltzmann_through_a_wide_band(temperature):
    ch = qogi.SpectralResponse([0.0, 40 * temperature / 1.438776877], [1.0, 1.0])
    expected = SIGMA_SB * temperature**4 / math.pi
    assert ch.band_radiance(temperature) == pytest.approx(expected, rel=1e-6)


def test_thesis_table4_open_band():
    ch = qogi.SpectralResponse([1852.0, 6667.0], [1.0, 1.0], name="open")
    assert ch.band_radiance(288.7) == pytest.approx(2.09, abs=0.005)


def test_radiometric_temperature_round_trip_vectorised():
    ch = qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0])
    t = np.linspace(200.0, 1500.0, 301).reshape(7, 43)
    back = ch.radiometric_temperature(ch.band_radiance(t))
    assert back.shape == t.shape
    assert np.max(np.abs(back - t)) < 1e-6


def test_wien_peak():
    t = 300.0
    nu = np.linspace(100.0, 2000.0, 190001)
    peak = nu[np.argmax(qogi.planck_radiance(nu, t))]
    assert peak == pytest.approx(2.821439372 * t / 1.438776877, abs=0.02)


@pytest.mark.parametrize(
    "call, words",
    [
        (lambda: qogi.planck_radiance(3000.0, -5.0), ["temperature_K", "> 0", "-5"]),
        (lambda: qogi.planck_radiance(3000.0, float("nan")), ["temperature_K", "nan"]),
        (lambda: qogi.SpectralResponse([], []), ["at least 2"]),
        (
            lambda: qogi.SpectralResponse([1.0, 3.0, 2.0], [1, 1, 1]),
            ["strictly increasing", "nu_cm1[2]"],
        ),
        (lambda: qogi.SpectralResponse([1.0, 2.0, 3.0], [1, 1]), ["same length"]),
        (lambda: qogi.SpectralResponse([1.0, 2.0], [1, -1]), ["response", ">= 0"]),
    ],
)
def test_bad_input_raises_value_error_naming_the_argument(call, words):
    with pytest.raises(ValueError) as err:
        call()
    for w in words:
        assert w in str(err.value)


def test_radiometric_temperature_rejects_negative_radiance():
    ch = qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="n")
    with pytest.raises(ValueError, match="band_radiance"):
        ch.radiometric_temperature(-1.0)


def test_csv_round_trip_and_wavelength_header(tmp_path):
    ch = qogi.SpectralResponse([2900.0, 3000.0, 3100.0], [0.1, 1.0, 0.2], name="x")
    p = tmp_path / "ch.csv"
    ch.to_csv(p)
    back = qogi.SpectralResponse.from_csv(p)
    np.testing.assert_array_equal(back.nu_cm1, ch.nu_cm1)
    np.testing.assert_array_equal(back.response, ch.response)
    assert back.name == "ch"
    q = tmp_path / "wl.csv"
    q.write_text("wavelength_um,transmittance\n3.2,1.0\n3.4,1.0\n")
    wl = qogi.SpectralResponse.from_csv(q)
    assert wl.nu_cm1[0] == pytest.approx(1e4 / 3.4)
    bad = tmp_path / "bad.csv"
    bad.write_text("nu,r\n3000,1\n3100,abc\n")
    with pytest.raises(ValueError, match=r"bad.csv:3"):
        qogi.SpectralResponse.from_csv(bad)


def test_pickle_keeps_the_channel():
    ch = qogi.SpectralResponse([2900.0, 3100.0], [1.0, 0.5], name="p")
    back = pickle.loads(pickle.dumps(ch))
    assert back.name == "p"
    assert back.band_radiance(300.0) == ch.band_radiance(300.0)
