"""Structured backgrounds of synthetic scenes (qogi.synth.backdrop, render.Background):
textured skies, drifting clouds, walls with seams and shadows, pipe racks;
and the renderer showing them exactly where there is no gas."""

import numpy as np
import pytest

from qogi import synth
from qogi.synth import backdrop, render


def test_texture_has_the_stated_rms_and_correlation_and_follows_its_seed():
    a = backdrop.texture_field(128, 160, rms_K=0.3, correlation_px=5.0, seed=4)
    assert np.std(a) == pytest.approx(0.3, rel=1e-9)
    assert abs(a.mean()) < 1e-12
    # Correlated over a few pixels, nearly independent far away.
    r1 = np.corrcoef(a[:, :-1].ravel(), a[:, 1:].ravel())[0, 1]
    r30 = np.corrcoef(a[:, :-30].ravel(), a[:, 30:].ravel())[0, 1]
    assert r1 > 0.9 and abs(r30) < 0.2
    np.testing.assert_array_equal(a, backdrop.texture_field(128, 160, 0.3, 5.0, seed=4))
    assert not np.allclose(a, backdrop.texture_field(128, 160, 0.3, 5.0, seed=5))


def test_clouds_drift_exactly_by_their_speed_and_have_soft_edges():
    c = backdrop.CloudField(96, 128, 6.0, cover=0.35, size_px=12.0, drift_px_s=(3.0, -2.0), seed=1)
    a0, a1 = c.amount(0.0), c.amount(2.0)
    # 2 s at (3, -2) px/s: 6 px right and 4 px up, exactly (away from the wrap).
    np.testing.assert_allclose(a1[10:80, 6:], a0[14:84, :-6], atol=1e-9)
    cover = float(np.mean(c.amount(0.0) > 0.5))
    assert 0.15 < cover < 0.6
    assert np.mean((a0 > 0.02) & (a0 < 0.98)) > 0.03  # soft edges, not a step
    assert c.temperature(0.0).max() == pytest.approx(6.0, abs=1e-6)
    assert not c.static


def test_wall_has_seams_bolts_and_a_shadow_of_the_stated_steps():
    bg = render.Background(
        "wall", 303.15, seam_K=3.0, bolt_K=2.0, shadow_K=8.0, shadow_x_fraction=0.5, seed=2
    )
    m = bg.temperature_map(120, 160)
    right = m[:, 120:]
    assert np.isclose(right, 303.15).mean() > 0.7  # the sunlit sheet
    assert np.isclose(right, 300.15).any() and np.isclose(right, 305.15).any()
    # Far left of the edge the shadow is 8 K colder.
    assert np.median(m[:, :20]) == pytest.approx(295.15, abs=1e-6)
    assert bg.static and bg.structured


def test_pipe_rack_has_hot_and_cold_pipes_with_sharp_edges():
    m = render.Background("pipe-rack", 278.15, pipe_hot_K=25.0, pipe_cold_K=8.0).temperature_map(
        120, 160
    )
    # A pipe's centre reaches its full excess, its limb 70 % of it.
    assert 278.15 + 0.7 * 25.0 - 1e-9 <= m.max() <= 303.15 + 1e-9
    assert 270.15 - 1e-9 <= m.min() <= 278.15 - 0.7 * 8.0 + 1e-9
    assert np.median(m) == pytest.approx(278.15)
    assert np.max(np.abs(np.diff(m, axis=1))) > 10.0  # a step within one pixel


def test_background_table_entries_are_checked():
    with pytest.raises(ValueError, match="unknown background field"):
        render.Background.from_dict({"kind": "sky", "texture_rms": 0.3})
    with pytest.raises(ValueError, match="texture_K"):
        render.Background("sky", None, texture_K=-1.0)
    with pytest.raises(ValueError, match="kind"):
        render.Background("brick", 290.0)


def test_every_preset_background_builds_and_five_have_structure():
    structured = []
    for name in synth.presets():
        bg = render.Background.from_dict(synth.preset(name)["scene"]["background"], seed=3)
        m = bg.temperature_map(24, 32)
        assert m.shape == (24, 32) and np.isfinite(m).all()
        if bg.structured:
            structured.append(name)
    assert len(structured) >= 5
    kinds = {synth.preset(n)["scene"]["background"]["kind"] for n in structured}
    assert {"sky", "wall", "pipe-rack"} <= kinds
    directions = {synth.preset(n)["release"]["wind_direction_deg"] for n in structured}
    assert {0.0, 180.0} <= directions  # wind from either side


def _small_scene():
    from test_render import small_scene

    return small_scene()


def test_renderer_shows_a_structured_background_exactly_where_there_is_no_gas():
    sim, cam = _small_scene()
    bg = render.Background(
        "sky",
        None,
        sky_top_K=250.0,
        sky_bottom_K=265.0,
        texture_K=0.3,
        texture_px=3.0,
        cloud_K=5.0,
        cloud_px=8.0,
        cloud_drift_px_s=(20.0, 0.0),
        seed=1,
    )
    r = render.SceneRenderer(sim, cam, bg, training_rays=300)
    ch = r.forward.channels[0]
    for f in (2, 7):
        frame = r.render_frame(f)[0]
        t = bg.temperature_map(48, 64, float(sim.times_s[f]))
        clear = sim.column_density(f)["CH4"] == 0
        assert clear.sum() > 1000
        np.testing.assert_allclose(frame[clear], ch.band_radiance(t[clear]), rtol=1e-6)
    # The clouds moved between the frames: the clear sky changed with them.
    t2, t7 = (bg.temperature_map(48, 64, float(sim.times_s[f])) for f in (2, 7))
    assert np.abs(t7 - t2).max() > 1.0
