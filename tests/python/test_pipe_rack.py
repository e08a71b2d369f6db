"""A pipe rack behind the plume (issue 31): the gas emits in front of the cold
structure and absorbs in front of pipes hotter than itself, and over a pipe
as hot as the gas it is nearly invisible. The background, the velocity's
column proxy and the surfaces' columns take each pixel's own sign and
sensitivity, and the self-checks say when what is left still fails."""

import dataclasses

import numpy as np
import pytest

from qogi.pipeline import selfchecks
from qogi.pipeline.background_choice import percentile_background, pixel_sign
from qogi.pipeline.columns import PROXY_MIN_SENSITIVITY, fill_insensitive, sensitivity_weight
from qogi.pipeline.selfchecks import SurfaceEvidence

#: Band radiances [arbitrary units] of the rack (cold), a hot pipe, the gas.
L_RACK, L_PIPE, L_GAS = 10.0, 14.0, 12.0


def _rack(h=24, w=40):
    """A background (h, w): the rack, with a hot pipe on columns 16-23."""
    bg = np.full((h, w), L_RACK)
    bg[:, 16:24] = L_PIPE
    return bg


def _frames(bg, t=80, seed=0, gas_every=2, tau=0.2, noise=0.01):
    """Frames (T, 1, h, w): a thin gas (absorptance ``tau``) over the rows
    8-15 in one frame of ``gas_every``, L = L_bg + tau (L_gas - L_bg)."""
    rng = np.random.default_rng(seed)
    f = np.repeat(bg[None], t, axis=0) + noise * rng.standard_normal((t,) + bg.shape)
    f[::gas_every, 8:16] += tau * (L_GAS - bg[8:16])
    return f[:, None]


def test_the_gas_sign_per_pixel_is_its_radiance_against_the_background():
    bg = _rack()
    sign = pixel_sign(bg[None], [L_GAS], [1.0])[0]
    assert (sign[:, 16:24] == -1).all()  # the hot pipe: the gas absorbs
    assert (sign[:, :16] == 1).all() and (sign[:, 24:] == 1).all()
    # A background at the gas's own radiance keeps the channel's sign.
    bg[:, 0] = L_GAS
    assert (pixel_sign(bg[None], [L_GAS], [1.0])[0][:, 0] == 1).all()


def test_the_percentile_background_over_a_hot_pipe_takes_the_high_tail():
    bg = _rack()
    frames = _frames(bg)
    one_sign, _ = percentile_background(frames, np.array([1.0]), 5.0)
    per_pixel, held = percentile_background(frames, np.array([1.0]), 5.0, np.array([L_GAS]))
    gas_rows = slice(8, 16)
    pipe = (gas_rows, slice(16, 24))
    # One sign for the channel takes the gas's absorbing frames as the
    # pipe's background: 0.2 x 2 = 0.4 below it, 40 noise.
    assert np.median(bg[pipe] - one_sign[0][pipe]) > 0.35
    # The pixel's own sign: within the noise's percentile (~2 noise).
    assert np.abs(per_pixel[0] - bg).max() < 0.05
    assert not held.any()


def test_the_proxy_weight_undoes_the_pipes_sign_and_sensitivity():
    bg = _rack()
    # The same thin gas over the whole field: contrast tau (L_gas - L_bg).
    tau = 0.1
    contrast = tau * (L_GAS - bg)  # +0.2 on the rack, -0.2 on the pipe
    w = sensitivity_weight(bg, L_GAS, 1.0)
    # Over the median background (the rack) the gas reads as there: 0.2
    # everywhere, the pipe's absorption brought to the rack's emission.
    np.testing.assert_allclose(contrast * w, 0.2, rtol=1e-5)
    # A uniform background leaves the signed contrast as it was (the gas
    # colder than a warm wall: the channel's sign -1, the factor 1).
    np.testing.assert_array_equal(sensitivity_weight(np.full((4, 5), L_PIPE), L_GAS, -1.0), 1.0)
    # A cold pipe (twice as sensitive) is brought down to the rack's; a
    # pipe half as sensitive is not raised (its background's error would be).
    bg[:, 2] = L_RACK - 2.0
    bg[:, 3] = L_RACK + 1.0
    w = sensitivity_weight(bg, L_GAS, 1.0)
    assert w[0, 2] == pytest.approx(0.5) and w[0, 3] == pytest.approx(1.0)
    # A pipe as hot as the gas carries no gas signal, only noise: tapered
    # linearly to zero below PROXY_MIN_SENSITIVITY of the rack's.
    bg[:, 30] = L_GAS
    bg[:, 31] = L_GAS - 0.5 * PROXY_MIN_SENSITIVITY * (L_GAS - L_RACK)
    w = sensitivity_weight(bg, L_GAS, 1.0)
    assert (w[:, 30] == 0).all()
    assert w[0, 31] == pytest.approx(0.5)
    assert np.abs(w).max() <= 1.0


def test_columns_over_a_background_as_hot_as_the_gas_are_interpolated_and_counted():
    t, n = 5, 30
    truth = np.tile(np.exp(-0.5 * ((np.arange(n) - 15) / 5.0) ** 2), (t, 1))
    cols = {"CH4": truth.copy()}
    sigs = {"CH4": np.full((t, n), 0.01)}
    weak = np.zeros((t, n), bool)
    weak[:, 14:17] = True
    cols["CH4"][weak] = 30.0  # the amplified noise of an invisible gas
    filled, total = fill_insensitive(cols, sigs, weak, "CH4")
    # Linear across a 3-sample gap at the peak of a Gaussian of 5 samples:
    # at most 1 - exp(-0.5 (2 / 5)^2) = 0.077 below it.
    assert np.abs(cols["CH4"] - truth).max() < 0.08
    assert (cols["CH4"][weak] <= truth[weak]).all()
    assert filled / total == pytest.approx(truth[weak].sum() / truth.sum(), rel=0.1)
    # The self-check: a tenth of the column interpolated fails and widens
    # the interval by that share; 1 % does not.
    big = SurfaceEvidence(pixel_frames=1, insensitive_column=10.0, column_sum=100.0)
    m, failed = selfchecks.failure_terms(big)
    assert m["insensitive_fraction"] == pytest.approx(0.1)
    assert dict(failed)["insensitive_fraction"] == pytest.approx(0.1)
    small = SurfaceEvidence(pixel_frames=1, insensitive_column=1.0, column_sum=100.0)
    assert "insensitive_fraction" not in dict(selfchecks.failure_terms(small)[1])
    assert selfchecks.CODES["insensitive_fraction"] == "background-insensitive"


def test_a_background_wrong_on_one_surface_flags_the_others_velocity():
    gas = dict(gas_contrast_sum=100.0 * 50, gas_pixel_frames=50)
    right = SurfaceEvidence(pixel_frames=100, deficit_sq=0.0, pixels=10, **gas)
    wrong = SurfaceEvidence(pixel_frames=100, deficit_sq=10 * 15.0**2 / 2, pixels=10, **gas)
    evidence = {0: right, 1: wrong, 2: right}
    assert wrong.measures()["background_residual_noise"] == pytest.approx(15.0)
    worst, contrast = selfchecks.plume_residual(evidence, 0)
    assert worst == pytest.approx(15.0) and contrast == pytest.approx(100.0)
    # Surface 0's own checks are clean; the plume's is not: 15 noise
    # against gas of 100 noise widens it by 15 %.
    ev = dataclasses.replace(right, plume_residual=worst, plume_contrast=contrast)
    m, failed = selfchecks.failure_terms(ev)
    assert m["background_residual_noise"] == 0.0
    assert dict(failed) == {"plume_residual_noise": pytest.approx(0.15)}
    assert selfchecks.CODES["plume_residual_noise"] == "background-residual-plume"
    # Every background right: nothing to flag.
    clean = dict.fromkeys(range(3), right)
    assert selfchecks.plume_residual(clean, 0)[0] == 0.0
    # The wrong surface itself is flagged by its own check, not the plume's.
    assert selfchecks.plume_residual(evidence, 1)[0] == 0.0
