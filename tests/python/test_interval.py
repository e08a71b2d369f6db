"""The rate's 90 % interval (qogi.pipeline.budget.interval90) against the
distribution it claims, and the line-shape curves (qogi.pipeline.budget_terms) against
analytic saturating models."""

import math

import numpy as np
import pytest

from qogi.pipeline import budget_terms as budget
from qogi.pipeline.budget import Z90, interval90

# -- the interval --------------------------------------------------------------


def test_the_quantile_is_the_normal_distributions():
    from statistics import NormalDist

    assert abs(Z90 - NormalDist().inv_cdf(0.95)) < 1e-12


def test_relative_terms_alone_give_the_log_normal_interval():
    lo, hi = interval90(2.0, 0.0, 0.2)
    assert lo == pytest.approx(2.0 * math.exp(-Z90 * 0.2), rel=1e-12)
    assert hi == pytest.approx(2.0 * math.exp(Z90 * 0.2), rel=1e-12)
    # Symmetric in the logarithm: the estimate is the geometric centre.
    assert math.sqrt(lo * hi) == pytest.approx(2.0, rel=1e-12)


def test_additive_terms_alone_give_mean_plus_minus_z_sigma():
    assert interval90(2.0, 0.3, 0.0) == pytest.approx((2.0 - Z90 * 0.3, 2.0 + Z90 * 0.3))
    # A zero rate with temporal scatter: symmetric about zero.
    assert interval90(0.0, 0.3, 0.5) == pytest.approx((-Z90 * 0.3, Z90 * 0.3))


def test_small_terms_reduce_to_the_linear_quadrature():
    m, a, r = 5.0, 0.01, 0.002
    lo, hi = interval90(m, a, r)
    half = Z90 * math.hypot(a, m * r)
    assert lo == pytest.approx(m - half, rel=1e-5)
    assert hi == pytest.approx(m + half, rel=1e-5)


def test_an_unmeasured_level_reaches_zero():
    # A relative term of 100 % (the velocimetry's level not measured): the
    # interval spans zero on the near side, the log-normal's far side above.
    lo, hi = interval90(2.0, 0.1, 1.0)
    assert lo == pytest.approx(2.0 - math.hypot(2.0, Z90 * 0.1))
    assert lo < 0 < 2.0 * math.exp(Z90) <= hi
    # Just below 100 % it does not.
    assert interval90(2.0, 0.0, 0.99)[0] > 0


def test_a_negative_rate_mirrors_the_positive_one():
    lo, hi = interval90(-2.0, 0.1, 0.3)
    plo, phi = interval90(2.0, 0.1, 0.3)
    assert (lo, hi) == pytest.approx((-phi, -plo))


def test_the_interval_covers_the_truth_ninety_percent_of_the_time():
    # The model the interval claims: each relative term a log-normal factor
    # between the truth and the estimate, the temporal scatter additive.
    rng = np.random.default_rng(18)
    truth, rel = 1.0, (0.10, 0.05, 0.17)  # velocity, column, line shape
    add = 0.06
    s = math.sqrt(sum(r * r for r in rel))
    n = 20000
    factor = np.exp(sum(rng.normal(0.0, r, n) for r in rel))
    est = truth * factor + rng.normal(0.0, add, n)
    lo, hi = np.array([interval90(m, add, s) for m in est]).T
    below, above = np.mean(truth < lo), np.mean(truth > hi)
    print("log-normal misses: truth below", below, "above", above)
    # 90 % within the Monte Carlo's error (0.2 %) and the additive and
    # multiplicative parts' overlap (hypot is exact for neither alone),
    # the misses split evenly between the sides.
    assert 0.88 < 1 - below - above < 0.92
    assert 0.035 < below < 0.065 and 0.035 < above < 0.065
    # The symmetric interval of the same sigma covers as often but misses
    # lopsidedly: where the rate reads low (the truth above the interval,
    # as in the cross-rule validation) three times as often.
    half = Z90 * np.hypot(add, est * s)
    lin_below, lin_above = np.mean(truth < est - half), np.mean(truth > est + half)
    print("linear misses: truth below", lin_below, "above", lin_above)
    assert lin_above > 2 * lin_below
    assert lin_above > above + 0.015


# -- the line-shape curves ---------------------------------------------------------


class _Saturating:
    """A plume model whose contrast saturates: L = A (1 - exp(-k N)) with the
    column N = x sigma (one species, or a mixture of fixed composition)."""

    def __init__(self, amplitude, k=50.0, composition=None):
        self.a, self.k = amplitude, k
        self.composition = composition or {"CH4": 1.0}

    def column_density(self, fractions, temperature, sigma_m, ambient_K):
        return {sp: np.asarray(fractions[sp], float) * sigma_m for sp in self.composition}

    def background_radiance(self, background_K):
        return np.array([1.0])

    def band_radiance(self, fractions, temperature, sigma_m, ambient_K, background_K):
        total = sum(np.asarray(fractions[sp], float) for sp in self.composition)
        c = self.a * -np.expm1(-self.k * total * sigma_m)
        return (1.0 + c)[:, None]


def _ratios(used, alts, fractions):
    return budget.line_shape_ratios(
        used, alts, 0, fractions, lambda x: np.full_like(x, 295.0), 0.1, 295.0, 295.0
    )


def test_ratios_at_equal_contrast_match_the_analytic_inverse():
    used, alt = _Saturating(1.0), _Saturating(1.25)
    cols, ratios = _ratios(used, [alt], lambda x: {"CH4": x})
    n = cols["CH4"]
    # A (1 - e^-kN) = A' (1 - e^-kN')  =>  N' = -ln(1 - A/A' (1 - e^-kN)) / k
    expected = -np.log1p(-(1.0 / 1.25) * -np.expm1(-50.0 * n)) / 50.0 / n
    # Interpolated in log-log on the 40-plume grid: within 1.5 % of the
    # inverse (the saturated end, where the column grows fastest).
    np.testing.assert_allclose(ratios[0], expected, rtol=0.015)
    # Thin: equal slopes A k = A' k' would give 1; here the alternative is
    # 25 % brighter, so 0.8 of the column.
    assert ratios[0][0] == pytest.approx(0.8, rel=1e-3)


def test_beyond_the_alternatives_saturation_the_ratio_holds_its_last_value():
    # The alternative saturates at 0.8 of the used model's contrast: the used
    # model's thickest plumes show contrasts it cannot reach at any column.
    used, alt = _Saturating(1.0), _Saturating(0.8)
    cols, ratios = _ratios(used, [alt], lambda x: {"CH4": x})
    n = cols["CH4"]
    reachable = -np.expm1(-50.0 * n) < 0.8 * -np.expm1(-50.0 * n[-1] * 1.0)
    assert (~reachable).any()
    r = ratios[0]
    last = np.flatnonzero(reachable)[-1]
    # Not falling back to 1 (the alternative's largest column over the used
    # one's): the deviation grows with the column and stays at its largest.
    assert np.all(r[last + 1 :] == r[last])
    assert r[-1] > 1.5
    assert np.all(np.diff(r) >= -1e-12)


def test_a_known_composition_gives_every_species_the_same_ratios():
    # Each species' columns are its share of the same plumes; the ratios are
    # those of the one species alone at the same total.
    comp = {"CH4": 0.5, "CO2": 0.5}
    used, alt = _Saturating(1.0, composition=comp), _Saturating(1.1, composition=comp)

    def mix(x):
        return {"CH4": 0.5 * x, "CO2": 0.5 * x}

    cols, ratios = _ratios(used, [alt], mix)
    np.testing.assert_array_equal(cols["CH4"], cols["CO2"])
    alone, alone_ratios = _ratios(_Saturating(1.0), [_Saturating(1.1)], lambda x: {"CH4": x})
    np.testing.assert_allclose(cols["CH4"], 0.5 * alone["CH4"], rtol=1e-12)
    np.testing.assert_allclose(ratios, alone_ratios, rtol=1e-9)
