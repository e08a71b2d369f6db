"""The result knows when its assumptions failed (qogi.pipeline.selfchecks), and the
automatic background looks at the background's own structure along each
surface (qogi.pipeline.background_choice.choose)."""

import dataclasses

import numpy as np
import pytest

from qogi.pipeline import selfchecks
from qogi.pipeline.background_choice import STRUCTURE_SIGMA, choose
from qogi.pipeline.selfchecks import SurfaceEvidence
from qogi.pipeline.surfaces import Surface


def _surface_samples(surf):
    xy, n, dl = surf.samples(step_px=1.0)
    tt = (np.arange(len(xy)) + 0.5) / len(xy)
    return [(xy, n, dl, tt)]


def _frames_with_background(bg, t=50, noise=0.01, seed=0):
    rng = np.random.default_rng(seed)
    return bg[None, None] + noise * rng.standard_normal((t, 1) + bg.shape)


def test_auto_background_sees_texture_between_gas_free_strips():
    h, w = 60, 80
    surf = Surface([(10, 30), (70, 30)], name="S")
    samples = _surface_samples(surf)
    # A sky gradient: straight between the strips, beside the surface is exact.
    sky = 10.0 + 0.002 * np.arange(w)[None, :] + 0.001 * np.arange(h)[:, None]
    smooth = choose(_frames_with_background(sky), [surf], samples, np.array([1.0]))
    assert smooth["method"] == "beside-surface", smooth["reason"]
    assert smooth["structure"][0] < 1.0
    # The same sky with a static texture 20x the noise (0.3 K at 15 mK).
    rng = np.random.default_rng(5)
    texture = 0.2 * np.repeat(rng.standard_normal(w // 4), 4)[None, :]
    textured = choose(_frames_with_background(sky + texture), [surf], samples, np.array([1.0]))
    assert textured["method"] == "percentile", textured["reason"]
    assert textured["structure"][0] > STRUCTURE_SIGMA
    assert "structure" in textured["reason"]


def _evidence(bg_error, gas_every=3, t=120, n=60, seed=0):
    """A surface's sign-aware contrast in noise units: Gaussian noise, gas
    of 30 noise on the middle third in one frame of ``gas_every``, and a
    background wrong by ``bg_error`` (n,) noise (positive: too high)."""
    rng = np.random.default_rng(seed)
    c = rng.standard_normal((t, n)) - bg_error[None, :]
    c[::gas_every, n // 3 : 2 * n // 3] += 30.0
    at_bound = c < -2.0  # the inversion finds no column above zero there
    return SurfaceEvidence.of(c, at_bound)


def test_a_right_background_passes_every_self_check():
    m, failed = selfchecks.failure_terms(_evidence(np.zeros(60)))
    assert failed == []
    assert m["background_residual_noise"] < 1.0
    assert m["negative_fraction"] < 0.01
    assert m["at_bound_fraction"] < 0.05


def test_a_textured_background_fails_the_residual_and_widens_by_its_size():
    rng = np.random.default_rng(3)
    error = 20.0 * rng.standard_normal(60)  # a texture of 20 noise RMS
    ev = _evidence(error)
    m, failed = selfchecks.failure_terms(ev)
    keys = {k for k, _ in failed}
    assert {"background_residual_noise", "negative_fraction", "at_bound_fraction"} <= keys
    # The residual estimates the texture's RMS from its half below the floor.
    assert m["background_residual_noise"] == pytest.approx(20.0, rel=0.35)
    # A residual of 20 noise against gas of ~30 noise: more than half the
    # signal, so the rate is not measured (term 1).
    ratio = m["background_residual_noise"] / ev.mean_gas_contrast_noise()
    assert ratio > selfchecks.NOT_MEASURED_ABOVE
    assert dict(failed)["background_residual_noise"] == 1.0
    # A texture of 6 noise (beyond the threshold) is sized by its ratio to the gas.
    small = _evidence(0.3 * error)
    m, failed = selfchecks.failure_terms(small)
    ratio = m["background_residual_noise"] / small.mean_gas_contrast_noise()
    assert dict(failed)["background_residual_noise"] == pytest.approx(ratio)


def test_flow_reversals_are_the_share_of_the_gross_flux_against_the_surface():
    ev = SurfaceEvidence(flux_against=2.0, flux_abs=10.0, pixel_frames=1)
    m, failed = selfchecks.failure_terms(ev)
    assert m["reversed_fraction"] == pytest.approx(0.2)
    assert dict(failed)["reversed_fraction"] == pytest.approx(0.4)
    # A third reversed moves the net by two thirds: not measured.
    ev = SurfaceEvidence(flux_against=3.4, flux_abs=10.0, pixel_frames=1)
    assert dict(selfchecks.failure_terms(ev)[1])["reversed_fraction"] == 1.0


def test_evidence_adds_over_blocks():
    a, b = _evidence(np.zeros(60), seed=1), _evidence(np.zeros(60), seed=2)
    total = SurfaceEvidence()
    total += a
    total += b
    assert total.pixel_frames == a.pixel_frames + b.pixel_frames
    assert total.at_bound == a.at_bound + b.at_bound


def test_inpainting_fills_the_structure_where_the_gas_never_leaves():
    from qogi.pipeline.background_choice import inpaint_held

    rng = np.random.default_rng(2)
    t, h, w = 150, 40, 60
    y, x = np.mgrid[0:h, 0:w]
    noise = 0.01
    # A gradient plus seams every 12 px (the structure), noise on top.
    bg = 10.0 + 0.003 * y + 0.2 * ((x % 12) < 2)
    frames = bg[None, None] + noise * rng.standard_normal((t, 1, h, w))
    # Gas in every frame over a band of columns 20-31 (it never leaves):
    # a fluctuating excess of 10-110 noise.
    frames[:, :, :, 20:32] += noise * rng.uniform(10, 110, (t, 1, h, 12))
    pct = np.percentile(frames, 5, axis=0)
    out, held = inpaint_held(frames, pct, np.array([1.0]), 5.0)
    band = np.zeros((h, w), bool)
    band[:, 20:32] = True
    assert held[band].mean() > 0.95 and held[~band].mean() < 0.02
    # The percentile holds the gas (>= 10 noise); the filled background is
    # within a fraction of the seams' 20 noise of the truth, seams included
    # where the gas never left (the seam at columns 24-25 is 2 px of 12).
    assert (pct[0][band] - bg[band]).mean() > 9 * noise
    err = np.abs(out[0] - bg)[band]
    assert np.median(err) < 3 * noise
    # Outside the held band the percentile is untouched.
    np.testing.assert_array_equal(out[0][~held], pct[0][~held])


def _band_of_gas(texture_noise: float, seed: int = 3):
    """Frames (T, 1, h, w) of a gradient (plus a static pixel texture of
    ``texture_noise`` RMS, in noise units) with gas in every frame over
    columns 20-31 (5-65 noise), and their 5th-percentile background."""
    rng = np.random.default_rng(seed)
    t, h, w = 150, 40, 60
    y, _x = np.mgrid[0:h, 0:w]
    noise = 0.01
    bg = 10.0 + 0.003 * y + texture_noise * noise * rng.standard_normal((h, w))
    frames = bg[None, None] + noise * rng.standard_normal((t, 1, h, w))
    frames[:, :, :, 20:32] += noise * rng.uniform(5, 65, (t, 1, h, 12))
    return frames, np.percentile(frames, 5, axis=0)


def test_the_held_pixels_background_error_is_tried_on_a_ring_of_known_pixels():
    from qogi.pipeline.background_choice import held_background_error, inpaint_held

    errors = {}
    for texture in (0.0, 100.0):
        frames, pct = _band_of_gas(texture)
        out, held = inpaint_held(frames, pct, np.array([1.0]), 5.0)
        assert held[:, 20:32].mean() > 0.9
        errors[texture] = held_background_error(frames, out, held)
    # Behind a smooth gradient the inpainting is right to the noise, a small
    # part of the gas's ~35-noise contrast; behind a texture of 100 noise
    # that no neighbour predicts it is as wrong as the gas is strong.
    assert errors[0.0] < 0.2
    assert errors[100.0] > 1.0
    # Nothing held: nothing to try.
    frames, pct = _band_of_gas(0.0)
    assert np.isnan(held_background_error(frames, pct, np.zeros(pct.shape[1:], bool)))


def test_a_held_background_as_wrong_as_the_gas_is_strong_means_the_rate_is_not_measured():
    key = "held_background_error"
    limit = selfchecks.THRESHOLDS[key]
    for value, flagged in ((0.5 * limit, False), (float("nan"), False), (1.3 * limit, True)):
        _m, failed = selfchecks.failure_terms(SurfaceEvidence(held_error=value))
        terms = dict(failed)
        assert (key in terms) is flagged
        if flagged:
            assert terms[key] == 1.0 and selfchecks.CODES[key] == "background-held"


# -- end to end on small scenes ------------------------------------------------------


def _crosswind(tmp_path, background, seed=0, duration_s=4.0):
    """The outdoor stack release (10 kg/h, 4 m/s crosswind) in a small view
    (96x64 px of 3.9 cm at 10 m) in front of ``background``; its exit pixel."""
    import dataclasses

    import qogi
    from qogi import synth
    from qogi.synth import render

    rel = synth.preset_release("stack-10kgh-wind4-sky-gf320")
    cam = qogi.camera_preset("gf320")
    cam = dataclasses.replace(cam, width=96, height=64, ifov_rad=3 * cam.ifov_rad)
    exit_px = (12.0, 36.0)
    view = synth.View.framing(
        rel, exit_px, width_px=96, height_px=64, ifov_rad=cam.ifov_rad, distance_m=10.0
    )
    sim = synth.simulate(rel, view, duration_s=duration_s, frame_rate_hz=15.0, seed=seed)
    path = render.render_recording(sim, cam, background, tmp_path / "r.h5", seed=seed)
    return qogi.open_recording(path), exit_px


@pytest.fixture(scope="module")
def textured_sky(tmp_path_factory):
    from qogi.synth import render

    bg = render.Background(
        "sky", None, sky_top_K=250.0, sky_bottom_K=265.0, texture_K=0.3, texture_px=2.0
    )
    return _crosswind(tmp_path_factory.mktemp("textured"), bg)


def _surfaces(exit_px):
    x, y = exit_px
    return [Surface([(x + d, y - 20), (x + d, y + 20)], name=f"{d} px") for d in (15, 30)]


@pytest.mark.slow
def test_textured_sky_beside_surface_is_flagged_and_its_interval_reaches_the_truth(textured_sky):
    from qogi.pipeline import QuantifyConfig, quantify

    rec, exit_px = textured_sky
    res = quantify(
        rec, _surfaces(exit_px), QuantifyConfig(source=exit_px, background="beside-surface")
    )
    for s in res.surfaces:
        r = s.species["CH4"]
        codes = {w.code for w in res.warnings if w.surface == s.surface.name}
        # The straight line between the strips misses the texture: the
        # surface's own evidence says so, and the interval is widened by it.
        assert {"background-residual", "inversion-at-bound"} <= codes, codes
        assert r.uncertainty_terms_kg_h["assumptions"] > 0.2 * abs(r.mean_kg_h)
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], (r.mean_kg_h, r.ci90_kg_h)


@pytest.mark.slow
def test_textured_sky_auto_background_takes_the_inpainted_percentile(textured_sky):
    from qogi.pipeline import QuantifyConfig, quantify

    rec, exit_px = textured_sky
    res = quantify(rec, _surfaces(exit_px), QuantifyConfig(source=exit_px))
    assert res.info["background_choice"]["method"] == "percentile"
    assert "structure" in res.info["background_choice"]["reason"]
    for s in res.surfaces:
        r = s.species["CH4"]
        assert abs(r.error_vs_truth) < 0.25, r.error_vs_truth
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], (r.mean_kg_h, r.ci90_kg_h)
    # Every surface's background holds: none flags another's velocity.
    assert not {w.code for w in res.warnings} & {"background-residual-plume", "background-residual"}


@pytest.mark.slow
def test_a_background_wrong_on_one_surface_flags_the_velocity_of_the_other(tmp_path):
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.synth import render

    # A pipe rack (hot pipes 25 K above the structure, cold ones 8 K below):
    # where the gas never leaves the pixels near the source, the inpainted
    # background misses the pipes behind them.
    bg = render.Background(
        "pipe-rack", 278.15, pipe_hot_K=25.0, pipe_cold_K=8.0, texture_K=0.1, texture_px=3.0
    )
    rec, exit_px = _crosswind(tmp_path, bg)
    res = quantify(rec, _surfaces(exit_px), QuantifyConfig(source=exit_px))
    checks = res.info["self_checks"]
    limit = selfchecks.THRESHOLDS["background_residual_noise"]
    # The far surface's own background reads right, the near one's does not.
    assert checks["30 px"]["background_residual_noise"] < limit
    assert checks["15 px"]["background_residual_noise"] > limit
    assert checks["30 px"]["plume_residual_noise"] == checks["15 px"]["background_residual_noise"]
    far = {w.code for w in res.warnings if w.surface == "30 px"}
    assert "background-residual-plume" in far
    # The rule: every surface off by more than 25 % carries a warning of its own.
    for s in res.surfaces:
        codes = {w.code for w in res.warnings if w.surface == s.surface.name}
        assert abs(s.species["CH4"].error_vs_truth) <= 0.25 or codes, s.surface.name


def test_upwind_region_lies_behind_the_source_and_its_contrast_is_measured():
    surfaces = [Surface([(60, 10), (60, 50)]), Surface([(80, 10), (80, 50)])]
    mask = selfchecks.upwind_mask(100, 60, (30.0, 30.0), surfaces)
    assert mask is not None
    assert mask[:, :14].all() and not mask[:, 16:].any()  # x < 30 - 15 only
    assert selfchecks.upwind_mask(100, 60, None, surfaces) is None
    # A static background leaves noise there; a moving one its contrast.
    quiet = SurfaceEvidence(pixel_frames=1, upwind_sq=1.2 * 1000, upwind_n=1000)
    moving = SurfaceEvidence(
        pixel_frames=1,
        upwind_sq=40.0**2 * 1000,
        upwind_n=1000,
        gas_contrast_sum=80.0 * 10,
        gas_pixel_frames=10,
    )
    assert selfchecks.failure_terms(quiet)[1] == []
    m, failed = selfchecks.failure_terms(moving)
    assert m["upwind_contrast_noise"] == pytest.approx(40.0)
    assert dict(failed)["upwind_contrast_noise"] == pytest.approx(0.5)


def test_failed_terms_combine_in_quadrature_until_the_rate_is_not_measured():
    assert selfchecks.combined_term([]) == 0.0
    assert selfchecks.combined_term([("a", 0.3), ("b", 0.4)]) == pytest.approx(0.5)
    assert selfchecks.combined_term([("a", 0.12), ("b", 0.49)]) == 1.0


# -- drifting backgrounds (issue 31, item 2) -------------------------------------------


def _drifting_stack(drift_px_frame=(0.5, 0.07), t=60, h=48, w=64, seed=0):
    """Frames (T, 1, H, W) in noise units: a static gradient and texture, broken
    'clouds' (a smooth positive field of up to 60 noise) drifting by
    ``drift_px_frame`` per frame, a gas band (25 noise) moving 16 px per frame
    across the rows 18-30; and the true background (T, H, W)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w].astype(float)
    static = 0.3 * y + 2.0 * np.sin(x / 2.3) * np.cos(y / 3.1)
    k = rng.uniform(-0.25, 0.25, (12, 2))
    ph = rng.uniform(0, 2 * np.pi, 12)
    truth, frames = [], []
    for i in range(t):
        dx, dy = drift_px_frame[0] * i, drift_px_frame[1] * i
        c = sum(np.cos(a * (x - dx) + b * (y - dy) + p) for (a, b), p in zip(k, ph))
        bg = static + 60.0 * np.clip(c / 4.0, 0, 1)
        gas = np.zeros((h, w))
        gas[18:30] = 25.0 * (((x[18:30] - 16 * i) % w) < 20)
        truth.append(bg)
        frames.append(bg + gas + rng.standard_normal((h, w)))
    return np.asarray(frames)[:, None], np.asarray(truth)


def test_drift_evidence_separates_drifting_clouds_from_a_still_textured_background():
    from qogi.pipeline.background_choice import DRIFT_SIGMA, drift_evidence

    moving, _ = _drifting_stack()
    still, _ = _drifting_stack(drift_px_frame=(0.0, 0.0))
    sign = np.array([1.0])
    assert drift_evidence(moving, sign) > 2 * DRIFT_SIGMA
    assert drift_evidence(still, sign) < 0.5 * DRIFT_SIGMA


def test_drifting_background_follows_the_clouds_where_the_percentile_reads_them_as_gas():
    from qogi import _engine

    frames, truth = _drifting_stack(seed=1)
    f = np.ascontiguousarray(frames[:, 0], np.float32)
    times = np.arange(len(f)) / 15.0
    d = _engine.measure_drift(f, times)
    assert d["measured"]
    assert d["vx_px_s"] == pytest.approx(0.5 * 15, abs=0.1)
    assert d["vy_px_s"] == pytest.approx(0.07 * 15, abs=0.1)
    bg = _engine.DriftingBackground(f, times, d["vx_px_s"], d["vy_px_s"], 1.0)
    static = np.percentile(f, 5.0, axis=0)
    inner = (slice(4, -4), slice(8, -8))
    err_d, err_p = [], []
    for i in range(5, len(f), 10):
        err_d.append((bg.at(times[i]) - truth[i])[inner])
        err_p.append((static - truth[i])[inner])
    err_d, err_p = np.asarray(err_d), np.asarray(err_p)
    # The drifting estimate: the percentile's own offset (~-1.6 noise) and a
    # noise's scatter; the whole-run percentile misses every passing cloud.
    assert -2.5 < err_d.mean() < 0.0
    assert err_d.std() < 1.5
    assert np.sqrt(np.mean(err_p**2)) > 5 * np.sqrt(np.mean(err_d**2))


def test_held_pixels_from_the_source_keep_only_the_parts_connected_to_it():
    from qogi.pipeline.background_choice import held_from_source

    held = np.zeros((40, 60), bool)
    held[18:22, 5:50] = True  # the plume's base, from the source at x = 5
    held[2:8, 30:40] = True  # a cloud's edge the drifting layer missed
    held[30:34, 52:58] = True
    near = held_from_source(held, (4.0, 20.0))
    assert near[18:22, 5:50].all() and near.sum() == 4 * 45
    assert not held_from_source(held, (55.0, 12.0)).any()  # nothing within 6 px


def _steady_core_over_seams(seed=4):
    """Frames (T, 1, h, w) of a textured plate (a 2-px-correlated texture of
    5 noise RMS) with seams, 1 px lines 40 noise bright (the gas's sign), one 2 px
    below the source (x 60, y 70), and a steady core rising from it: 12 px wide, 150
    noise at its centre, constant in time (it never leaves, nor fluctuates:
    the spread test cannot see it); returns (frames, the background, core
    mask, source)."""
    import cv2

    rng = np.random.default_rng(seed)
    t, h, w, noise = 60, 80, 120, 0.01
    y, x = np.mgrid[0:h, 0:w].astype(float)
    tex = cv2.GaussianBlur(rng.standard_normal((h, w)), (0, 0), 2.0)
    bg = 10.0 + 0.002 * y + 5 * noise * tex / tex.std()
    bg[:, 50] += 40 * noise  # seams, in the gas's sign: one beside the core...
    bg[72, :] += 40 * noise  # ...one 2 px below the source, across the frame
    bg[:, 100] += 40 * noise
    source = (60.0, 70.0)
    core_profile = 150 * noise * np.exp(-0.5 * ((x - source[0]) / 3.0) ** 2)
    core = (y <= source[1]) & (y >= source[1] - 40)
    gas = np.where(core, core_profile, 0.0)
    frames = (bg + gas)[None, None] + noise * rng.standard_normal((t, 1, h, w))
    return frames, bg, core & (np.abs(x - source[0]) <= 4), source


def test_the_steady_core_is_found_by_standing_out_not_by_its_spread_and_seams_are_not():
    from qogi.pipeline.background_choice import inpaint_held, standing_from_source

    frames, bg, core, source = _steady_core_over_seams()
    pct = np.percentile(frames, 5, axis=0)
    noise = np.array([0.01])
    # The spread test alone holds nothing: the core does not fluctuate.
    _, held0 = inpaint_held(frames, pct, np.array([1.0]), 5.0, noise)
    assert held0[core].mean() < 0.05
    stand = standing_from_source(pct, np.ones_like(pct), noise, source)
    assert stand[core].mean() > 0.95
    # The seams stand out as much and pass by the source, but they are lines.
    far = np.zeros_like(stand)
    far[:, 90:] = True
    assert not stand[far].any() and stand.sum() < 3 * core.sum()
    # Held and inpainted from the textured neighbours: the core's background
    # to the texture's size (5 noise; no neighbour predicts a texture of
    # 2 px), where the percentile held the gas (~120 noise).
    out, held = inpaint_held(frames, pct, np.array([1.0]), 5.0, noise, source_xy=source)
    assert held[core].all()
    err = (out[0] - bg)[core] / 0.01
    assert np.median(pct[0][core] - bg[core]) / 0.01 > 60
    assert np.sqrt(np.mean(err**2)) < 8
    # Without the source, nothing is taken for a core.
    _, held_ns = inpaint_held(frames, pct, np.array([1.0]), 5.0, noise)
    assert not held_ns.any()


def test_a_hot_pipe_along_the_plume_is_not_inpainted_away():
    """A narrow plume the gas never leaves runs along a hot pipe (as on the
    pipe rack's seed 4, where the inpainting filled the pipe from the cold
    sky around it: columns at the inversion's bound, +158 %): over the pipe
    the gas absorbs, and its background lies above the high percentile, so
    the inpainting is bounded there."""
    from qogi.pipeline.background_choice import inpaint_held

    rng = np.random.default_rng(7)
    t, h, w, noise = 120, 60, 120, 0.01
    y, x = np.mgrid[0:h, 0:w].astype(float)
    pipe = np.abs(y - 30) <= 2
    bg = 10.0 + 1.0 * pipe  # the pipe 100 noise hotter than the sky
    band = np.abs(y - (26 + 0.1 * x)) <= 4  # the plume, crossing the pipe over ~80 px
    sign = np.where(pipe, -1.0, 1.0)[None]  # it emits over the sky, absorbs over the pipe
    gas = noise * rng.uniform(10, 60, (t, 1, h, w)) * band
    frames = (bg + noise * rng.standard_normal((t, 1, h, w))) + sign * gas
    img = np.where(sign >= 0, np.percentile(frames, 5, axis=0), np.percentile(frames, 95, axis=0))
    out, held = inpaint_held(frames, img, sign, 5.0, np.array([noise]))
    on = pipe & band & held
    assert on.sum() > 0.8 * (pipe & band).sum()
    err = (out[0] - bg)[on] / noise
    # At worst the percentile, which holds the gas's least absorption (10-20
    # noise); never the sky's radiance, 100 noise below (-101 unbounded).
    assert err.min() > -30.0, err.min()
    assert np.median(np.abs(err)) < 16.0
    # By how much the inpainting stood beyond the bound is kept: the
    # background residual's evidence that the frames contradict it there.
    out2, held2, clip = inpaint_held(frames, img, sign, 5.0, np.array([noise]), return_clip=True)
    np.testing.assert_array_equal(out2, out)
    assert np.sqrt(np.mean(clip[0][on] ** 2)) / noise > 20
    assert not clip[0][~held2].any() and (clip >= 0).all()
    # On a surface across the pipe, the residual measured against the
    # bounded background is nothing; against the inpainting, its error.
    cols = np.nonzero(on.any(axis=0))[0][:5]
    c = ((frames[:, 0, 28:33, :][:, :, cols] - out[0][28:33][:, cols]) * -1 / noise).reshape(t, -1)
    floor = c - (clip[0][28:33][:, cols] / noise).reshape(1, -1)
    bounded = SurfaceEvidence.of(c, np.zeros_like(c, bool)).measures()
    shown = SurfaceEvidence.of(c, np.zeros_like(c, bool), floor).measures()
    limit = selfchecks.THRESHOLDS["background_residual_noise"]
    assert bounded["background_residual_noise"] < limit < shown["background_residual_noise"]


def test_a_seam_under_the_plumes_path_is_structure_the_gas_free_samples_do_not_see():
    """The strips are gas-free and the surface's gas-free samples lie on the
    straight line between them, but a seam 30 noise deep crosses the surface
    where the gas passes half the time: its low percentile shows the seam
    (``tank-emission`` seed 3 read -69 to -76 % on the strips)."""
    h, w, t, noise = 60, 80, 50, 0.01
    surf = Surface([(40, 5), (40, 55)], name="S")
    samples = _surface_samples(surf)
    y, x = np.mgrid[0:h, 0:w].astype(float)
    bg = 10.0 + 0.001 * y
    seam = np.abs(y - 30) <= 1.5
    frames = _frames_with_background(bg - 30 * noise * seam, t=t, noise=noise, seed=2)
    band = np.abs(y - 30) <= 8  # the plume's path along the surface
    for i in range(0, t, 2):
        frames[i, 0][band] += 60 * noise
    choice = choose(frames, [surf], samples, np.array([1.0]))
    assert choice["strips"][0] < 2.5
    assert choice["structure"][0] > STRUCTURE_SIGMA, choice["structure"]
    assert choice["method"] == "percentile", choice["reason"]
    # Without the seam, the same plume leaves the strips in place.
    clean = _frames_with_background(bg, t=t, noise=noise, seed=2)
    for i in range(0, t, 2):
        clean[i, 0][band] += 60 * noise
    assert choose(clean, [surf], samples, np.array([1.0]))["method"] == "beside-surface"


@pytest.mark.slow
def test_the_drifting_backgrounds_static_layer_inpaints_the_plumes_base(tmp_path):
    # Broken clouds drifting across a 10 kg/h crosswind stack (seed 2): the
    # static layer is a percentile over the run, and where the gas never
    # leaves the pixels (the plume's base) it held the gas: the columns read
    # 0.49-0.77 of the truth and the rates -32 % with every interval missing.
    # Its held pixels are now found and inpainted as the percentile's are.
    import qogi
    from qogi import synth
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.synth.render import synthesize

    name = "stack-10kgh-wind4-clouds-gf320"
    path = synthesize(name, tmp_path / "c.h5", duration_s=10.0, seed=2)
    rec = qogi.open_recording(path)
    ex, ey = synth.preset(name)["scene"]["exit_pixel"]
    side = np.sign(np.cos(np.radians(synth.preset_release(name).wind_direction_deg)))
    surfaces = [
        Surface([(ex + side * d, ey - 45), (ex + side * d, ey + 45)], name=f"{d} px")
        for d in (38, 115)
    ]
    res = quantify(rec, surfaces, QuantifyConfig(source=(ex, ey)))
    assert res.info["background_choice"]["method"] == "drifting"
    for s in res.surfaces:
        r = s.species["CH4"]
        assert abs(r.error_vs_truth) < 0.25, (s.surface.name, r.error_vs_truth)
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], s.surface.name
    assert np.isfinite(res.info["self_checks"][surfaces[0].name]["held_background_error"])


def test_a_wall_edge_crossing_the_surface_is_structure_not_drift_and_the_percentile_holds():
    """A sunlit wall (absorption: the gas lowers the radiance) with a shadow
    edge crossing a vertical surface and a seam: the background is still, so
    ``auto`` takes the sign-aware percentile (the straight line between the
    strips misses the edge), not the drifting layers; and that percentile
    along the surface is the wall's own radiance within a noise."""
    from qogi.pipeline.background_choice import DRIFT_SIGMA, drift_evidence
    from qogi.pipeline.sampling import _bilinear

    h, w, t, noise = 64, 48, 60, 0.01
    y, x = np.mgrid[0:h, 0:w].astype(float)
    wall = 10.0 - 0.8 * 0.5 * (1 - np.tanh((x - 10 - 0.4 * y) / 1.0))  # shadow to the left
    wall[:, 30:32] -= 0.3  # a seam
    rng = np.random.default_rng(3)
    frames = wall[None, None] + noise * rng.standard_normal((t, 1, h, w))
    for i in range(t):  # puffs absorbing 20 noise, across the surface half the time
        if i % 2 == 0:
            frames[i, 0, 20:44, :] -= 0.2 * (((x[20:44] - 9 * i) % w) < 16)
    surf = Surface([(24, 4), (24, 60)], name="S")  # the edge crosses it near y = 35
    samples = _surface_samples(surf)
    sign = np.array([-1.0])
    assert drift_evidence(frames, sign) < DRIFT_SIGMA
    choice = choose(frames, [surf], samples, sign)
    assert choice["method"] == "percentile", choice["reason"]
    high = np.percentile(frames[:, 0], 95.0, axis=0)  # the absorbing gas's side
    xy = samples[0][0]
    err = (_bilinear(high, xy) - _bilinear(wall, xy)) / noise
    assert np.abs(err).max() < 3.0
    # The straight line between the strips misses the edge by its step.
    line = np.interp(xy[:, 1], [xy[0, 1], xy[-1, 1]], _bilinear(wall, xy[[0, -1]]))
    assert np.abs(line - _bilinear(wall, xy)).max() / noise > 20.0


# -- the steady column (issue 31): a quiet column's pattern need not be its gas -------


def test_column_fluctuation_is_the_most_fluctuating_lines_rms_over_their_mean():
    rng = np.random.default_rng(3)
    t = np.arange(200)[:, None]
    mean = np.array([0.1, 1.0, 2.0, 2.0, 1.0])  # the first line carries < 1/4 of the most
    steady = mean * (1 + 0.05 * np.sin(2 * np.pi * t / 9 + np.arange(5)))
    steady[:, 0] += rng.normal(0, 1.0, 200)  # a faint line's noise is left out
    assert selfchecks.column_fluctuation(steady) == pytest.approx(0.05 / np.sqrt(2), rel=0.05)
    puffs = mean * rng.lognormal(0, 0.4, (200, 5))
    assert selfchecks.column_fluctuation(puffs) > 0.3
    assert np.isnan(selfchecks.column_fluctuation(steady[:19]))  # too few frames
    assert np.isnan(selfchecks.column_fluctuation(np.zeros((50, 5))))  # no gas


def test_a_steady_column_fails_below_its_threshold_and_widens_by_the_pattern_speed():
    limit = selfchecks.THRESHOLDS["column_fluctuation"]
    quiet = SurfaceEvidence(fluctuation_sum=2 * 0.5 * limit, fluctuation_n=2)
    measures, failed = selfchecks.failure_terms(quiet)
    assert measures["column_fluctuation"] == pytest.approx(0.5 * limit)
    assert failed == [("column_fluctuation", selfchecks.STEADY_COLUMN_TERM)]
    assert selfchecks.CODES["column_fluctuation"] == "steady-column"
    # Half the gas's speed read as the pattern's still lies inside the interval.
    from qogi.pipeline.budget import interval90

    ratio = selfchecks.STEADY_COLUMN_SPEED_RATIO
    lo, hi = interval90(ratio, 0.0, selfchecks.STEADY_COLUMN_TERM)
    assert lo < ratio and hi == pytest.approx(1.0)
    _, failed = selfchecks.failure_terms(
        SurfaceEvidence(fluctuation_sum=limit * 2, fluctuation_n=1)
    )
    assert failed == []
    _, failed = selfchecks.failure_terms(SurfaceEvidence())  # not measured: no warning
    assert failed == []


def _lab_column(tmp_path, release, rate_hz, duration_s, seed=1):
    """The lab release (5 SLPM CH4 before a 12 C plate, GF320 optics) in a
    small view, 48x72 px of 1.96 mm; its exit pixel."""
    import qogi
    from qogi import synth
    from qogi.synth import render

    cam = qogi.camera_preset("gf320")
    cam = dataclasses.replace(cam, width=48, height=72, frame_rate_hz=rate_hz)
    exit_px = (23.5, 68.0)
    view = synth.View.framing(
        release, exit_px, width_px=48, height_px=72, ifov_rad=cam.ifov_rad, distance_m=1.5
    )
    sim = synth.simulate(release, view, duration_s=duration_s, frame_rate_hz=rate_hz, seed=seed)
    bg = render.Background("plate", 285.15)
    path = render.render_recording(sim, cam, bg, tmp_path / "lab.h5", seed=seed)
    return qogi.open_recording(path), exit_px


def _lab_surfaces(exit_px):
    x, y = exit_px
    return [Surface([(x - 16, y - h), (x + 16, y - h)], name=f"{h} px") for h in (20, 40, 60)]


@pytest.mark.slow
def test_a_quiet_column_is_flagged_steady_and_a_puffing_lab_plume_is_not(tmp_path):
    """The laminar preset's release (its speed wave's pattern slower than the
    gas) reads low and says so, with intervals that reach the truth; the
    puff plume of the GF320 lab preset, in the same view, passes."""
    from qogi import synth
    from qogi.pipeline import QuantifyConfig, quantify

    quiet, exit_px = _lab_column(
        tmp_path, synth.preset_release("lab-ch4-5slpm-laminar-gf320"), 100.0, 1.0
    )
    res = quantify(quiet, _lab_surfaces(exit_px), QuantifyConfig(source=exit_px))
    for s in res.surfaces:
        r = s.species["CH4"]
        codes = {w.code for w in res.warnings if w.surface == s.surface.name}
        assert "steady-column" in codes, codes
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], (r.mean_kg_h, r.ci90_kg_h)
    puffs, exit_px = _lab_column(tmp_path, synth.preset_release("lab-ch4-5slpm-gf320"), 15.0, 4.0)
    res = quantify(puffs, _lab_surfaces(exit_px), QuantifyConfig(source=exit_px))
    assert "steady-column" not in {w.code for w in res.warnings}


# -- the flux level's time of flight (issue 31): gas faster than the frames follow ------


def test_the_transports_unexplained_share_is_weighted_by_each_lines_column():
    from qogi.measure import velocimetry as vel
    from qogi.pipeline.velocity import transport_unexplained

    nan = float("nan")
    tf = vel.TransportFlux(
        flux=np.ones(4),
        line_column=np.array([1.0, 3.0, 5.0, 0.0]),
        velocity=np.ones(4),
        displacement=np.array([2.0, 2.0, nan, 2.0]),
        axis="up",
        unexplained=np.array([0.1, 0.5, nan, 0.9]),  # line 2 unsolved, line 3 holds no gas
    )
    assert transport_unexplained(tf) == pytest.approx((0.1 * 1 + 0.5 * 3) / 4)
    tf.unexplained = np.full(4, nan)
    assert np.isnan(transport_unexplained(tf))


def test_frames_in_view_is_the_frame_beyond_the_source_over_the_displacement():
    from qogi.measure import velocimetry as vel
    from qogi.pipeline.velocity import frames_in_view

    nan = float("nan")
    d = np.array([nan, 20.0, 26.0, 30.0, nan, nan, nan, nan, nan, nan, nan])
    for axis, source, path in (("right", 2.0, 8.0), ("left", 8.0, 8.0), ("down", 0.0, 10.0)):
        tf = vel.TransportFlux(np.ones(11), np.ones(11), np.ones(11), d, axis)
        assert frames_in_view(tf, source) == pytest.approx(path / 26.0), axis
    tf = vel.TransportFlux(np.ones(11), np.ones(11), np.ones(11), np.full(11, nan), "up")
    assert np.isnan(frames_in_view(tf, 5.0))


def test_gas_in_view_for_too_few_frames_flags_the_rate_as_not_measured():
    limit = selfchecks.THRESHOLDS["transport_frames_in_view"]
    assert selfchecks.CODES["transport_frames_in_view"] == "transport-unresolved"
    assert "transport_frames_in_view" in selfchecks.BELOW
    _, failed = selfchecks.failure_terms(SurfaceEvidence(in_view_sum=2 * limit, in_view_n=1))
    assert failed == []
    # An 8 m/s wind at 15 Hz and 1.3 cm pixels: 52 px per frame, 136 px in view.
    m, failed = selfchecks.failure_terms(SurfaceEvidence(in_view_sum=2 * 136 / 52, in_view_n=2))
    assert m["transport_frames_in_view"] == pytest.approx(136 / 52)
    assert failed == [("transport_frames_in_view", 1.0)]
    _, failed = selfchecks.failure_terms(SurfaceEvidence())  # no flux level: not measured
    assert failed == []


def test_gas_in_view_for_too_few_frames_at_the_surfaces_own_speed_is_flagged_too():
    # A time of flight that reads 0.7 of the speed counts 4.7 frames in view
    # (passes); the surface's columns carry its rate at 1.7 times that
    # speed: 2.8 frames at it (the envelope's 8 m/s wall, seed 2: +28 %).
    limit = selfchecks.THRESHOLDS["surface_frames_in_view"]
    assert "surface_frames_in_view" in selfchecks.BELOW
    assert selfchecks.CODES["surface_frames_in_view"] == "transport-unresolved"

    def ev(ratio):
        return SurfaceEvidence(
            in_view_sum=4.7,
            in_view_n=1,
            surface_speed_num=ratio,
            surface_speed_den=1.0,
            transport_speed_sum=1.0,
            transport_speed_n=1,
        )

    m, failed = selfchecks.failure_terms(ev(1.7))
    assert m["surface_frames_in_view"] == pytest.approx(4.7 / 1.7) and limit > 4.7 / 1.7
    assert failed == [("surface_frames_in_view", 1.0)]
    m, failed = selfchecks.failure_terms(ev(1.1))  # 4.3 frames: a 4 m/s cell's
    assert m["surface_frames_in_view"] > limit and failed == []
    m, failed = selfchecks.failure_terms(ev(0.6))  # slower than the time of flight
    assert np.isnan(m["surface_frames_in_view"]) and failed == []
    m, failed = selfchecks.failure_terms(
        dataclasses.replace(ev(1.0), surface_speed_den=0.0)  # no column: columns-missing's
    )
    assert np.isnan(m["surface_frames_in_view"])
    assert [k for k, _ in failed] == ["implied_speed_ratio"]


def test_a_time_of_flight_worse_than_unrelated_frames_flags_the_rate_as_not_measured():
    # The residual of a displaced comparison of two frames unrelated to each
    # other is twice the anomaly's variance: above that the fit explains
    # less than no transport at all.
    rng = np.random.default_rng(0)
    a, b = rng.standard_normal((2, 100000))
    assert np.var(a - b) / np.var(b) == pytest.approx(2.0, rel=0.02)
    limit = selfchecks.THRESHOLDS["transport_unexplained"]
    assert limit == 2.0
    assert selfchecks.CODES["transport_unexplained"] == "transport-unresolved"
    assert "transport_unexplained" not in selfchecks.BELOW
    # Clean and noisy fits that read the rate within 10 % (the envelope's
    # wind block): 0.02-1.9.
    _, failed = selfchecks.failure_terms(SurfaceEvidence(unexplained_sum=1.9, unexplained_n=1))
    assert failed == []
    # The wall at -20 K in an 8 m/s wind, seed 2: a fit locked on a slow
    # displacement, 2.5.
    m, failed = selfchecks.failure_terms(SurfaceEvidence(unexplained_sum=5.0, unexplained_n=2))
    assert m["transport_unexplained"] == pytest.approx(2.5)
    assert failed == [("transport_unexplained", 1.0)]


def test_transport_speed_is_the_median_of_the_solved_lines_displacement():
    from qogi.measure import velocimetry as vel
    from qogi.pipeline.velocity import transport_speed

    nan = float("nan")
    d = np.array([nan, 7.0, 9.0, 8.0, nan])
    tf = vel.TransportFlux(np.ones(5), np.ones(5), np.ones(5), d, "up")
    assert transport_speed(tf) == pytest.approx(8.0)
    tf = vel.TransportFlux(np.ones(5), np.ones(5), np.ones(5), np.full(5, nan), "up")
    assert np.isnan(transport_speed(tf))


def test_columns_that_need_many_times_the_measured_speed_flag_the_rate_as_not_measured():
    limit = selfchecks.THRESHOLDS["implied_speed_ratio"]
    assert selfchecks.CODES["implied_speed_ratio"] == "columns-missing"
    assert "implied_speed_ratio" not in selfchecks.BELOW

    def evidence(speed_num, speed_den, transport=(0.4, 2)):
        return SurfaceEvidence(
            surface_speed_num=speed_num,
            surface_speed_den=speed_den,
            transport_speed_sum=transport[0],
            transport_speed_n=transport[1],
        )

    # A column-weighted speed of 0.3 m/s where the time of flight read 0.2.
    m, failed = selfchecks.failure_terms(evidence(3.0, 10.0))
    assert m["implied_speed_ratio"] == pytest.approx(1.5)
    assert failed == []
    # The textured lab's 2 cm surface: the percentile took the steady core
    # into the background and its columns need ~4000 times the speed.
    m, failed = selfchecks.failure_terms(evidence(0.2 * 4000 * 1e-3, 1e-3))
    assert m["implied_speed_ratio"] == pytest.approx(4000)
    assert m["implied_speed_ratio"] > limit
    assert failed == [("implied_speed_ratio", 1.0)]
    # A flux through a surface whose columns sum to nothing or less.
    m, failed = selfchecks.failure_terms(evidence(0.5, -1e-4))
    assert m["implied_speed_ratio"] == float("inf")
    assert failed == [("implied_speed_ratio", 1.0)]
    # No time of flight (no source given, or another velocity), or no flux:
    # nothing to compare with.
    for ev in (evidence(3.0, 10.0, transport=(0.0, 0)), evidence(0.0, 10.0)):
        m, failed = selfchecks.failure_terms(ev)
        assert np.isnan(m["implied_speed_ratio"])
        assert failed == []


@pytest.mark.slow
def test_a_steady_core_is_inpainted_and_one_left_in_the_background_is_flagged(
    tmp_path, monkeypatch
):
    # The lab release before a textured plate: the gas never leaves the
    # pixels of its base, and hardly fluctuates there, so the temporal
    # percentile held it and the columns at 2 cm vanished (+195 % on the
    # 10 s record of seed 0, with no warning). The core stands out of the
    # percentile image far beyond the texture: found, inpainted, measured.
    import qogi
    from qogi.pipeline import QuantifyConfig, quantify
    from qogi.pipeline import background_choice as bc
    from qogi.pipeline.surfaces import truth_surfaces
    from qogi.synth.render import synthesize

    # 10 s: in 4 s the gas leaves the pixels 8-12 cm up too seldom for any
    # percentile (all surfaces -52 %, warned background-residual-plume).
    path = synthesize("lab-ch4-5slpm-textured-gf320", tmp_path / "lab.h5", duration_s=10.0, seed=0)
    rec = qogi.open_recording(path)
    surfaces, source = truth_surfaces(rec, heights_m=[0.02, 0.12], half_width_px=40)
    cfg = QuantifyConfig(gas_temperature="ambient", source=source)
    res = quantify(rec, surfaces, cfg)
    assert res.info["background_choice"]["method"] == "percentile"
    for s in res.surfaces:
        assert abs(s.species["CH4"].error_vs_truth) < 0.15, s.surface.name
    assert not [w for w in res.warnings if w.code == "columns-missing"]
    # A core the spatial test misses stays in the background: then the
    # columns-missing check flags the surface and its interval covers.
    monkeypatch.setattr(bc, "standing_from_source", lambda img, *a: np.zeros(img.shape[1:], bool))
    res = quantify(rec, surfaces, cfg)
    low = res.surfaces[0].species["CH4"]
    assert low.error_vs_truth > 0.5
    flagged = {w.to_dict().get("surface") for w in res.warnings if w.code == "columns-missing"}
    assert surfaces[0].name in flagged and surfaces[1].name not in flagged
    assert low.ci90_kg_h[0] <= low.truth_kg_h <= low.ci90_kg_h[1]
    ratios = [res.info["self_checks"][s.name]["implied_speed_ratio"] for s in surfaces]
    assert ratios[0] > 1000 * ratios[1] and ratios[1] < 3.0  # 12 cm holds its gas


def _wall_in_absorption(tmp_path, wind_m_s, seed):
    """The operating envelope's cell of 1 kg/h at 10 m in a ``wind_m_s``
    crosswind before a structured wall 20 K warmer than the gas (160x120 px
    of 1.3 cm, 3 s at 15 Hz, ``seed``), quantified with the defaults and the
    source given."""
    import qogi
    from qogi.apps import envelope as env
    from qogi.pipeline import QuantifyConfig, quantify

    cell = env.Cell(
        1.0, 10.0, -20.0, wind_m_s, "structured", "gf320", 3.0, seed, width_px=160, height_px=120
    )
    env.render_cell(cell, tmp_path / "wall.h5")
    lines, source = env.surfaces(cell)
    surfaces = [Surface([(a, b), (c, d)], name=f"S{i}") for i, (a, b, c, d) in enumerate(lines)]
    return quantify(
        qogi.open_recording(tmp_path / "wall.h5"), surfaces, QuantifyConfig(source=source)
    )


@pytest.mark.slow
def test_a_fit_reading_the_gas_slow_on_a_wall_is_flagged(tmp_path):
    """1 kg/h at 10 m in an 8 m/s wind before a structured wall 20 K warmer
    than the gas (the envelope's cell, seed 2; 2.6 frames in view by the
    truth).

    With the held background inpainted without the percentile's bound (as
    before it), the flux level's time of flight locked on a displacement a
    fifth of the gas's (19.7 frames in view, so ``transport_frames_in_view``
    passed) and read -90 / -70 / -78 % with no warning; it left 2.5 of the
    column's fluctuation unexplained, more than unrelated frames would.
    Flagged, the speed is taken as not measured (term 1); the interval of a
    rate read at a tenth of the truth still does not reach it (its far side
    is exp(1.645) = 5.2 times the rate: what a speed nothing measured can be
    bounded by is open).

    With the bound the time of flight reads 0.7 of the speed (4.7 frames in
    view by it, and 1.8 unexplained: both pass) and the first two surfaces
    +28 / +26 %: their own speed, 1.7 times the time of flight's, puts the
    gas in view for 2.8 frames (``surface_frames_in_view``).

    Since the surfaces keep the plume's faint wings (signed columns below the
    per-pixel test, issue 28) the unbounded inpainting no longer locks the
    time of flight (5.7 frames in view, +2 / +1 / -5 %), so that half of the
    scenario is gone from this test; the unexplained share's rule keeps its
    own tests above (``transport_unexplained``)."""
    import qogi
    from qogi.apps import envelope as env
    from qogi.pipeline import QuantifyConfig, quantify

    cell = env.Cell(
        1.0, 10.0, -20.0, 8.0, "structured", "gf320", 3.0, 2, width_px=160, height_px=120
    )
    env.render_cell(cell, tmp_path / "wall.h5")
    lines, source = env.surfaces(cell)
    surfaces = [Surface([(a, b), (c, d)], name=f"S{i}") for i, (a, b, c, d) in enumerate(lines)]
    rec = qogi.open_recording(tmp_path / "wall.h5")

    def flagged(res, surface):
        codes = {w.code for w in res.warnings if w.surface == surface.surface.name}
        return "transport-unresolved" in codes

    res = quantify(rec, surfaces, QuantifyConfig(source=source))
    for s in res.surfaces:
        r = s.species["CH4"]
        if abs(r.error_vs_truth) > 0.25:
            assert flagged(res, s), (s.surface.name, r.error_vs_truth)
            assert r.ci90_kg_h[1] >= 5.0 * r.mean_kg_h, (r.mean_kg_h, r.ci90_kg_h)
    assert any(abs(s.species["CH4"].error_vs_truth) > 0.25 for s in res.surfaces)


def _windy(tmp_path, wind_m_s):
    """1 kg/h from the outdoor stack in a ``wind_m_s`` crosswind, 10 m away
    before a plate 20 K colder than the gas, 2 s at 15 Hz in 128x64 px of
    1.3 cm (the operating envelope's scene, qogi.apps.envelope): its
    recording and the envelope's surfaces and source."""
    import qogi
    from qogi.apps import envelope as env

    cell = env.Cell(1.0, 10.0, 20.0, wind_m_s, "plate", "gf320", 2.0, 0, width_px=128, height_px=64)
    env.render_cell(cell, tmp_path / "wind.h5")
    lines, source = env.surfaces(cell)
    surfaces = [Surface([(a, b), (c, d)], name=f"S{i}") for i, (a, b, c, d) in enumerate(lines)]
    return qogi.open_recording(tmp_path / "wind.h5"), surfaces, source


@pytest.mark.slow
def test_gas_crossing_a_third_of_the_frame_per_frame_is_flagged_and_its_interval_covers(tmp_path):
    """At 8 m/s the gas moves ~52 px per frame (of 1.3 cm at 15 Hz) and is in
    view for 2-3 frames: the structures change beyond recognition between
    frames, and the flux level's time of flight read the envelope's scene
    -38 % with a tight interval and no warning (issue 28). Its fit explains
    no more of the column than nothing carried; the check says so and the
    interval covers whatever the level read."""
    from qogi.pipeline import QuantifyConfig, quantify

    rec, surfaces, source = _windy(tmp_path, 8.0)
    res = quantify(rec, surfaces, QuantifyConfig(source=source))
    limit = selfchecks.THRESHOLDS["transport_frames_in_view"]
    for s in res.surfaces:
        r = s.species["CH4"]
        assert res.info["self_checks"][s.surface.name]["transport_frames_in_view"] < limit
        codes = {w.code for w in res.warnings if w.surface == s.surface.name}
        assert "transport-unresolved" in codes
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], (r.mean_kg_h, r.ci90_kg_h)


@pytest.mark.slow
def test_a_wall_in_absorption_at_4_m_s_reads_within_its_interval(tmp_path):
    """1 kg/h at 10 m in a 4 m/s wind before a structured wall 20 K warmer
    than the gas (the envelope's cell, seed 0). The temporal percentile
    background stands ~1.5 noise on the gas's side of the truth on every
    gas-free pixel; the flux level's band, thresholded on the raw time
    average, then took in the whole frame and its line noise, and the three
    surfaces read -33 / -29 / -26 % with intervals missing the truth and no
    warning (docs/validation.md, "The percentile's noise offset")."""
    res = _wall_in_absorption(tmp_path, 4.0, 0)
    for s in res.surfaces:
        r = s.species["CH4"]
        assert abs(r.error_vs_truth) < 0.15, (s.surface.name, r.error_vs_truth)
        assert r.ci90_kg_h[0] <= r.truth_kg_h <= r.ci90_kg_h[1], (r.mean_kg_h, r.ci90_kg_h)


def test_the_held_pixels_image_operations_are_opencvs_run_in_the_engine():
    # The percentile background's morphology, resizing and inpainting run in
    # the engine's OpenCV (engine/background/held_pixels.h): the same values
    # as opencv-python's, which the pipeline no longer loads (issue 30).
    cv2 = pytest.importorskip("cv2")
    from qogi import _engine

    rng = np.random.default_rng(4)
    m = (rng.random((60, 80)) > 0.7).astype(np.uint8)
    assert np.array_equal(_engine.connected_components8(m), cv2.connectedComponents(m, 8)[1])
    disk = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    assert np.array_equal(_engine.dilate_disk(m, 3), cv2.dilate(m, disk))
    assert np.array_equal(_engine.open_disk(m, 3), cv2.morphologyEx(m, cv2.MORPH_OPEN, disk))
    img = rng.normal(0.0, 3.0, (61, 81)).astype(np.float32)
    area = cv2.resize(img, (41, 31), interpolation=cv2.INTER_AREA)
    np.testing.assert_allclose(_engine.resize_image(img, 41, 31, "area"), area, atol=1e-5)
    lin = cv2.resize(area, (81, 61), interpolation=cv2.INTER_LINEAR)
    np.testing.assert_allclose(_engine.resize_image(area, 81, 61, "linear"), lin, atol=1e-5)
    hole = np.zeros((61, 81), np.uint8)
    hole[20:35, 30:50] = 1
    np.testing.assert_allclose(
        _engine.inpaint_ns(img, hole, 3.0), cv2.inpaint(img, hole, 3.0, cv2.INPAINT_NS), atol=1e-4
    )
    with pytest.raises(ValueError, match="linear"):
        _engine.resize_image(img, 4, 4, "cubic")
    with pytest.raises(ValueError, match="differ in size"):
        _engine.inpaint_ns(img, hole[:10], 3.0)


def test_quantifying_with_a_percentile_background_does_not_load_opencv_python(tmp_path):
    # opencv-python is a second OpenCV in the process (~15-20 MB resident):
    # the pipeline's own numerics use the engine's.
    import subprocess
    import sys

    code = f"""
import sys
import qogi
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline.surfaces import truth_surfaces
from qogi.synth import render
render.synthesize("lab-ch4-5slpm-gf320", {str(tmp_path / "lab.h5")!r}, duration_s=1.0, seed=1)
rec = qogi.open_recording({str(tmp_path / "lab.h5")!r})
surf, src = truth_surfaces(rec, heights_m=[0.06], half_width_px=40)
res = quantify(rec, surf, QuantifyConfig(source=src, background="percentile"))
assert res.surfaces[0].species["CH4"].mean_kg_h > 0
print("cv2" in sys.modules)
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip().splitlines()[-1] == "False", out.stdout + out.stderr
