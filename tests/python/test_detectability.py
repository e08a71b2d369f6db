"""Probability of detection and the minimum-detectable column (issue 28,
item 4), and a detection limit that a blank cannot talk down."""

from __future__ import annotations

import math
import subprocess
import sys

import numpy as np
import pytest

import qogi
from qogi.apps.detectability import (
    PodCurve,
    PodScene,
    fit_logistic,
    min_detectable_column_map,
    render_scene,
    stated_limit_kg_h,
    trial,
)
from qogi.errors import UsageError
from qogi.pipeline.detection import DETECTION_SIGMA, noise_equivalent_column, significant_peak

#: A scene whose plume spans few pixels (quick to quantify): GF320 at 5 m.
SCENE = PodScene(distance_m=5.0, delta_T_K=8.0, wind_speed_m_s=1.0, plume_sigma_m=0.03)


def test_fit_logistic_recovers_a_known_curve_from_its_draws():
    # Outcomes drawn from PoD = 1 / (1 + exp(-(ln Q - ln 0.02) / 0.3)),
    # 400 per rate: the fit returns Q50 and s within their sampling error
    # (about 3 % and 10 %: computed from the binomial spread at these rates).
    rng = np.random.default_rng(1)
    q = np.repeat(0.02 * 2.0 ** np.arange(-3, 4), 400)
    p = 1 / (1 + np.exp(-(np.log(q) - math.log(0.02)) / 0.3))
    q50, s = fit_logistic(q, rng.random(q.size) < p)
    assert q50 == pytest.approx(0.02, rel=0.05) and s == pytest.approx(0.3, rel=0.15)
    # Perfectly separated outcomes still give a finite, steep curve.
    q50, s = fit_logistic([1, 1, 2, 2, 4, 4], [0, 0, 1, 1, 1, 1])
    assert 1 < q50 < 2 and 0 < s < 1
    with pytest.raises(ValueError, match="two or more rates"):
        fit_logistic([0, 1, 1], [0, 0, 1])


def test_pod_curve_reads_its_fit_and_its_90_percent_rate():
    c = PodCurve(PodScene(), 0.02, 0.3, [], [], None, 0.01)
    assert c.probability(0.02) == pytest.approx(0.5)
    assert c.probability(c.rate_at(0.9)) == pytest.approx(0.9)
    assert c.rate_at(0.9) == pytest.approx(0.02 * math.exp(0.3 * math.log(9)))
    assert c.probability(0.0) == 0.0


def test_the_rendered_release_holds_exactly_its_rate():
    # sum over the surface of column x pixel x speed is the rate (less the
    # Gaussian's tails beyond the surface's ends).
    rec, surface, truth = render_scene(SCENE, 0.05, seed=0)
    assert truth == pytest.approx(0.05, rel=1e-5)
    assert rec.n_channels == 1 and rec.n_frames == round(SCENE.record_s * 15)
    assert rec.scene.distance_m == SCENE.distance_m
    # The noise is the camera's NETD: the frame-to-frame spread of a pixel.
    diff = np.diff(rec.frames(0, rec.n_frames)[:, 0], axis=0)
    assert np.std(diff) / math.sqrt(2) == pytest.approx(rec.camera.netd_K, rel=0.05)
    with pytest.raises(UsageError, match="peak volume fraction"):
        render_scene(SCENE, 1e6, seed=0)


@pytest.mark.slow
def test_a_blank_is_not_detected_and_its_limit_is_an_upper_bound():
    # No gas: the time-averaged contrast's largest noise sample must not pass
    # for a one-pixel plume (it did: a limit 24x below the scene's real one).
    # Without a plume the limit takes the surface's length: above the limit
    # of the plume the scene would carry.
    t = trial(SCENE, 0.0, seed=2)
    assert not t.detected
    assert t.limit_kg_h > stated_limit_kg_h(SCENE)


def test_significant_peak_corrects_for_looking_at_every_sample():
    assert significant_peak(1) == DETECTION_SIGMA  # one sample: the per-pixel test
    assert significant_peak(200) == pytest.approx(3.48, abs=0.01)
    # Pure noise: its largest of n samples passes in about 5 % of draws.
    rng = np.random.default_rng(0)
    peaks = rng.standard_normal((4000, 200)).max(axis=1)
    assert np.mean(peaks >= significant_peak(200)) == pytest.approx(0.05, abs=0.012)


@pytest.mark.slow
def test_releases_well_above_the_curve_are_detected_and_well_below_are_not():
    lim = stated_limit_kg_h(SCENE)
    assert trial(SCENE, 4 * lim, seed=0).detected
    assert not trial(SCENE, 0.25 * lim, seed=0).detected


def test_min_detectable_column_is_k_plus_z_noise_columns_at_each_pixel():
    cam = qogi.camera_preset("gf320")
    from qogi.physics.forward import forward_model

    model = forward_model(cam.channels, ["CH4"])
    bg = np.array([[280.0, 285.0], [290.0, 293.15]])
    m = min_detectable_column_map(bg, cam, gas_K=293.15, ambient_K=293.15)
    z = 1.6448536269514722  # one-sided 95 %
    for (i, j), t in np.ndenumerate(bg[:1]):  # where the grid holds the temperature itself
        nec = noise_equivalent_column(model, "CH4", cam.netd_K, t, 293.15, 293.15)
        assert m[i, j] == pytest.approx((3 + z) * nec, rel=1e-4)
    # Between grid points: interpolated within 0.5 %.
    nec = noise_equivalent_column(model, "CH4", cam.netd_K, 285.0, 293.15, 293.15)
    assert m[0, 1] == pytest.approx((3 + z) * nec, rel=5e-3)
    # Less contrast, a larger column needed; none at all: nothing detectable.
    assert m[0, 0] < m[0, 1] < m[1, 0] and math.isinf(m[1, 1])
    with pytest.raises(ValueError, match="finite"):
        min_detectable_column_map(np.array([[np.nan]]), cam, 293.15, 293.15)


def test_pod_scene_and_command_line_refuse_bad_input_with_the_fix():
    with pytest.raises(UsageError, match="delta_T_K must be within"):
        PodScene(delta_T_K=0.0)
    with pytest.raises(UsageError, match="unknown camera preset"):
        PodScene(camera="nope")
    with pytest.raises(UsageError, match=r"plume .* spans .* pixels"):
        render_scene(PodScene(distance_m=0.5, plume_sigma_m=1.0), 0.01, 0)
    done = subprocess.run(
        [sys.executable, "-m", "qogi", "pod", "--wind-speed", "0"],
        check=False,
        capture_output=True,
        text=True,
    )
    assert done.returncode == 2 and "--wind-speed: must be > 0" in done.stderr


def test_the_command_line_writes_a_recordings_min_detectable_column_map(tmp_path, capsys):
    from qogi.apps.cli import main
    from qogi.apps.detectability import recording_min_detectable_column

    rec, _, _ = render_scene(SCENE, 0.0, seed=3)
    p = tmp_path / "blank.h5"
    rec.save(p)
    out = tmp_path / "mdc.npy"
    assert main(["pod", "--map", str(p), "--map-out", str(out)]) == 0
    assert "minimum-detectable column" in capsys.readouterr().out
    m = np.load(out)
    want, bg = recording_min_detectable_column(qogi.open_recording(p))
    assert m.shape == (rec.height, rec.width) and np.allclose(m, want, rtol=1e-6)
    # The blank's background is the plate: delta-T 8 K everywhere, one value.
    assert np.allclose(bg, SCENE.background_K, atol=0.02)
    assert np.ptp(m) < 0.01 * m.mean()
    assert main(["pod", "--map", str(p), "--map-out", str(tmp_path / "x.txt")]) == 2


def test_a_step_between_two_rates_is_refined_between_them():
    from qogi.apps.detectability import Trial, _refining_rates

    def t(q, d):
        return Trial(q, 0, d, q, 1.0)

    step = [t(0.0, False), t(1.0, False), t(1.0, False), t(2.0, True), t(2.0, True)]
    assert _refining_rates(step) == pytest.approx([2 ** (1 / 3), 2 ** (2 / 3)])
    # A rate already between 0 and 1: the fit sees the slope, no refining.
    assert _refining_rates([*step, t(1.5, True), t(1.5, False)]) == []


def test_a_pod_whose_speed_the_flow_cannot_measure_says_it_is_an_upper_bound():
    # The envelope's 1 g/h at 1.5 m in a 2 m/s wind: 68 px per 15 Hz frame,
    # beyond the flow's 64 px; the pipeline found no speed and decided
    # nothing, where the PoD (given the speed) said 74 %.
    fast = PodScene(camera="gf320", distance_m=1.5, wind_speed_m_s=2.0)
    assert fast.flow_displacement_px == pytest.approx(
        2.0 / (1.5 * qogi.camera_preset("gf320").ifov_rad * 15.0), rel=1e-9
    )
    assert fast.flow_displacement_px > 64 and not fast.speed_measurable
    # 10 m: 10 px per frame, in range
    assert PodScene(camera="gf320", distance_m=10.0, wind_speed_m_s=2.0).speed_measurable
    # still air far away: below 1 px even between every 4th frame
    slow = PodScene(camera="gf320", distance_m=30.0, wind_speed_m_s=0.01)
    assert slow.flow_displacement_px < 1 and not slow.speed_measurable
    curve = PodCurve(fast, 0.01, 0.2, [], [], None, 0.005)
    d = curve.to_dict()
    assert d["upper_bound"] is True and d["speed_measurable"] is False
    assert PodCurve(slow, 0.01, 0.2, [], [], None, 0.005).to_dict()["upper_bound"] is True
