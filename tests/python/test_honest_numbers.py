"""Honest numbers where the physics is uncertain (issue 18): the line shape as
a model choice and its term in the budget, source detection that cannot
zero a rate silently, the hot-gas warning, the background's choice and the
record-length advice."""

import numpy as np
import pytest

import qogi
from qogi import synth
from qogi.physics.forward import LineShape, forward_model
from qogi.pipeline import QuantifyConfig, quantify
from qogi.pipeline import budget_terms as budget
from qogi.pipeline.background_choice import choose
from qogi.pipeline.surfaces import Surface, detect_source, truth_surfaces
from qogi.synth import render

# -- the line shape -----------------------------------------------------------


def test_line_shape_text_round_trips_and_bad_text_is_a_clear_error():
    assert str(LineShape()) == "fixed:25+self"
    for text in ("fixed:25+self", "hapi+air", "fixed:40+air", "hapi+self"):
        assert str(LineShape.parse(text)) == text
    assert LineShape.parse("hapi") == LineShape("hapi", 25.0, True)
    for bad in ("voigt", "hapi:30", "fixed+both", "fixed:abc"):
        with pytest.raises(ValueError, match="line shape"):
            LineShape.parse(bad)
    assert QuantifyConfig(line_shape="hapi").line_shape == "hapi+self"
    assert len(LineShape().alternatives()) == 2


def _rendered(folder, preset: str, duration_s: float, seed: int, **kw):
    """A synthetic recording of ``preset`` rendered into ``folder``, opened."""
    p = folder / f"{preset}-{duration_s:.3g}s-seed{seed}.h5"
    render.synthesize(preset, p, duration_s=duration_s, seed=seed, **kw)
    return qogi.open_recording(p)


@pytest.fixture(scope="module")
def gf320_models():
    cam = qogi.camera_preset("gf320")
    return [
        forward_model(cam.channels, ["CH4"], line_shape=r)
        for r in ("fixed:25+self", "hapi+self", "fixed:25+air", "hapi+air")
    ]


def test_the_rules_differ_little_for_thin_plumes_and_much_for_thick_ones(gf320_models):
    used, *alts = gf320_models

    def contrast(m, x, sigma):
        return float(
            m.band_radiance({"CH4": x}, 295.0, sigma, 295.0, 285.0)[0]
            - m.background_radiance(285.0)[0]
        )

    thin = [abs(contrast(a, 0.01, 0.005) / contrast(used, 0.01, 0.005) - 1) for a in alts]
    thick = [abs(contrast(a, 0.5, 0.05) / contrast(used, 0.5, 0.05) - 1) for a in alts]
    print("thin", np.round(thin, 4), "thick", np.round(thick, 4))
    # Weak lines' cores dominate a thin plume (the wings' share is small);
    # in a thick one the saturated cores leave the wings to make the contrast.
    assert max(thin) < 0.02
    assert max(thick) > 0.05


def test_the_line_shape_term_is_large_where_the_plume_is_optically_thick(gf320_models):
    used, *alts = gf320_models
    grids, ratios = budget.line_shape_ratios(
        used,
        alts,
        0,
        lambda x: {"CH4": x},
        lambda x: np.full_like(x, 295.0),
        0.03,
        295.0,
        285.0,
    )
    grid = grids["CH4"]
    # Columns of a thin plume edge (1 % over 3 cm) and of a thick core (60 %).
    thin_c = used.column_density({"CH4": 0.01}, 295.0, 0.03, 295.0)["CH4"]
    thick_c = used.column_density({"CH4": 0.6}, 295.0, 0.03, 295.0)["CH4"]
    w = np.ones((4, 5))
    thin = budget.line_shape_systematic(np.full((4, 5), thin_c), w, grid, ratios)
    thick = budget.line_shape_systematic(np.full((4, 5), thick_c), w, grid, ratios)
    print(f"line-shape term: thin {thin:.4f}, thick {thick:.4f}")
    assert thin < 0.03
    assert thick > 3 * thin and thick > 0.05


@pytest.fixture(scope="module")
def lab_hapi_air(tmp_path_factory):
    """The ambient lab release rendered with HAPI's wings and air broadening."""
    return _rendered(
        tmp_path_factory.mktemp("cross"), "lab-ch4-5slpm-gf320", 20 / 15, 3, line_shape="hapi+air"
    )


def test_cross_rule_the_line_shape_term_covers_the_rule_the_renderer_used(lab_hapi_air):
    rec = lab_hapi_air
    assert rec.truth.attrs["line_shape"] == "hapi+air"
    surf, source = truth_surfaces(rec, heights_m=[0.04, 0.08], half_width_px=40)
    kw = dict(velocity="exit", exit_velocity_m_s=1.0, source=source, background="beside-surface")
    default = quantify(rec, surf, QuantifyConfig(**kw))
    matched = quantify(rec, surf, QuantifyConfig(line_shape="hapi+air", **kw))
    assert default.config.line_shape == "fixed:25+self"
    assert default.to_dict()["config"]["line_shape"] == "fixed:25+self"
    for a, b in zip(default.surfaces, matched.surfaces):
        r = a.species["CH4"]
        diff = abs(r.mean_kg_h / b.species["CH4"].mean_kg_h - 1)
        term = r.uncertainty_terms_kg_h["line shape"] / r.mean_kg_h
        print(
            f"{a.surface.name}: rules differ by {100 * diff:.1f} %, line-shape term "
            f"{100 * term:.1f} %"
        )
        # The rule matters for this plume, and the term is as large as the
        # difference the renderer's rule actually makes.
        assert diff > 0.01
        assert term >= 0.8 * diff


# -- source detection and rates against the flow --------------------------------


def _plume_image(width=50, height=100, source=(25.0, 92.0), neck=True):
    """A rising plume leaving through the top edge: the column falls along
    it (~z^(-2/3)) and it widens, except a wide, lazy exit that necks."""
    yy, xx = np.mgrid[0:height, 0:width].astype(float)
    z = np.clip(source[1] - yy, 0.5, None)
    width_px = 2.0 + 0.25 * z
    if neck:
        width_px += 8.0 * np.exp(-z / 4.0)  # wider at the exit than just above
    img = z ** (-2.0 / 3.0) * np.exp(-0.5 * ((xx - source[0]) / width_px) ** 2)
    img[yy > source[1] + 1] = 0.0
    return img


@pytest.mark.parametrize("neck", [False, True])
def test_source_is_where_the_column_is_strongest_not_where_the_plume_leaves(neck):
    x, y = detect_source(_plume_image(neck=neck))
    assert y > 80, (x, y)  # the exit at row 92, not the top edge
    assert abs(x - 25) < 5


def test_a_zero_or_reversed_rate_with_gas_on_the_surface_is_flagged():
    c = np.full((20, 10), 1e-4)
    sig = np.full((20, 10), 1e-6)
    w = np.full((20, 10), 0.01)
    assert budget.direction_check(np.full(20, 1e-5), c, sig, w) is None
    zero = budget.direction_check(np.zeros(20), c, sig, w)
    assert zero["reason"] == "zero" and zero["bound_kg_s"] == pytest.approx(1e-4 * 0.01 * 10)
    assert budget.direction_check(np.full(20, -1e-5), c, sig, w)["reason"] == "against"
    # No gas on the surface: a zero rate is what it should be.
    assert budget.direction_check(np.zeros(20), np.zeros((20, 10)), sig, w) is None


@pytest.fixture(scope="module")
def small_view(tmp_path_factory):
    """A 50 x 100 px lab view 0.75 m from the exit: the plume fills the
    width and leaves through the top edge."""
    rel = synth.preset_release("lab-ch4-5slpm-gf320")
    base = synth.preset_view("lab-ch4-5slpm-gf320")
    view = synth.View.framing(
        rel,
        (24.5, 95.0),
        width_px=50,
        height_px=100,
        ifov_rad=base.ifov_rad,
        distance_m=0.75,
        projection=base.projection,
    )
    sim = synth.simulate(rel, view, 3.0, 15.0, seed=1)
    cam = qogi.camera_preset("gf320")
    cam.width, cam.height = 50, 100
    p = tmp_path_factory.mktemp("small") / "small.h5"
    render.render_recording(sim, cam, render.Background("plate", 285.15), p, seed=1)
    return qogi.open_recording(p)


def test_small_view_with_the_plume_leaving_through_the_top_never_reads_a_silent_zero(small_view):
    rec = small_view
    surfs = [Surface([(5, y), (44, y)], name=f"row {y}") for y in (70, 50)]
    res = quantify(rec, surfs, QuantifyConfig())
    truth = rec.truth.emission_rate_kg_s["CH4"] * 3600
    print(res.summary())
    sx, sy = res.info["source_xy"]
    assert sy > 70, res.info["source"]  # the exit (row 95), not the top edge
    for s in res.surfaces:
        r = s.species["CH4"]
        lo, hi = r.ci90_kg_h
        assert hi > lo  # never a zero-width interval
        # Either the interval holds the truth, or the result says why not.
        assert lo <= truth <= hi or res.warnings, (r.mean_kg_h, r.ci90_kg_h, truth)


def test_a_reversed_source_is_flagged_and_its_interval_widened(ambient):
    rec = ambient
    surf, source = _lab_surfaces(rec)
    truth = rec.truth.emission_rate_kg_s["CH4"] * 3600
    # The source given above the plume: the surfaces count the rising gas as
    # flowing towards it, and the flux level reads the transport backwards.
    res = quantify(rec, surf, QuantifyConfig(source=(source[0], 5.0)))
    print(res.summary())
    for s in res.surfaces:
        r = s.species["CH4"]
        assert r.mean_kg_h < 0
        lo, hi = r.ci90_kg_h
        # Widened to what is known: the magnitude, either way (mirrored about
        # zero; on this 20-frame record the velocity level is not measured,
        # a 100 % term).
        assert lo == pytest.approx(-hi)
        assert lo <= -truth and hi >= truth, (r.ci90_kg_h, truth)
    assert res.warnings.has("flux-against-surface")


@pytest.mark.slow
def test_a_reversed_source_on_a_long_record_still_reaches_the_truth(tmp_path):
    # 10 s of the lab release with the source given above the plume: the
    # velocity level is measured here (10 % term), so the interval's reach
    # comes from the flux bound. The transport along the axis from the given
    # source finds no flux (a zero rate), the transport the other way the
    # gas's speed: at 4 cm the buoyancy scale alone (0.22 m/s) bounded the
    # flux at 0.075 kg/h, the reverse transport at 0.19, 0.23 at the upper
    # end of its relative terms, against the 0.2 kg/h truth.
    rec = _rendered(tmp_path, "lab-ch4-5slpm-gf320", 10.0, 1)
    surf, source = _lab_surfaces(rec)
    truth = rec.truth.emission_rate_kg_s["CH4"] * 3600
    res = quantify(rec, surf, QuantifyConfig(source=(source[0], 5.0)))
    print(res.summary())
    assert res.warnings.has("zero-rate-with-gas") or res.warnings.has("flux-against-surface")
    for s in res.surfaces:
        lo, hi = s.species["CH4"].ci90_kg_h
        assert lo <= -truth and hi >= truth, (s.surface.name, lo, hi, truth)


def test_a_reversed_source_is_flagged(ambient):
    rec = ambient
    surf, source = _lab_surfaces(rec)
    res = quantify(rec, surf, QuantifyConfig(source=(source[0], 5.0)))
    for s in res.surfaces:
        r = s.species["CH4"]
        assert r.mean_kg_h < 0 and r.ci90_kg_h[1] > 0  # widened across zero
    assert res.warnings.has("flux-against-surface")


# -- the hot-gas warning ---------------------------------------------------------


@pytest.fixture(scope="module")
def heated(tmp_path_factory):
    return _rendered(tmp_path_factory.mktemp("hot"), "lab-heated-ch4-55c-gf320", 20 / 15, 5)


@pytest.fixture(scope="module")
def ambient(tmp_path_factory):
    return _rendered(tmp_path_factory.mktemp("hot"), "lab-ch4-5slpm-gf320", 20 / 15, 5)


def _lab_surfaces(rec):
    return truth_surfaces(rec, heights_m=[0.04, 0.08], half_width_px=40)


def test_hot_gas_warning_fires_on_the_heated_single_channel_preset(heated):
    surf, source = _lab_surfaces(heated)
    exit_K = synth.preset_release("lab-heated-ch4-55c-gf320").exit_temperature_K
    res = quantify(
        heated,
        surf,
        QuantifyConfig(
            source=source, exit_temperature_K=exit_K, velocity="exit", exit_velocity_m_s=0.3
        ),
    )
    print(res.warnings)
    w = [d for d in res.warnings if d.code == "gas-temperature-suspect"]
    assert w, res.warnings
    # The bias direction and size: the assumed ambient temperature reads the
    # hotter gas's emission as more gas (x2.2 in docs/validation.md).
    assert w[0].data["direction"] == "high"
    assert 1.3 < w[0].data["bias_factor"] < 4.0
    # Every interval reaches down to the rate read at that bias, and so to
    # the truth (x2.0-2.4 below the rate at the assumed temperature).
    b = w[0].data["bias_factor"]
    truth = heated.truth.emission_rate_kg_s["CH4"] * 3600
    for s in res.surfaces:
        r = s.species["CH4"]
        lo, hi = r.ci90_kg_h
        assert lo <= r.mean_kg_h / b
        assert lo <= truth <= hi, (r.mean_kg_h, r.ci90_kg_h, truth)


@pytest.mark.slow
def test_hot_gas_warning_from_the_plume_rise_alone(tmp_path):
    # No exit temperature: the quantified rate (x2.2 too much gas) would
    # drive a faster rise than the velocimetry measures. On 6 s records
    # the ratio reads 0.78-0.94 over seeds 0-7 (this one 0.89), the
    # ambient release 0.97-1.11 (qogi.pipeline.hotgas.RISE_RATIO_THRESHOLD).
    heated = _rendered(tmp_path, "lab-heated-ch4-55c-gf320", 6.0, 7)
    surf, source = _lab_surfaces(heated)
    res = quantify(heated, surf, QuantifyConfig(source=source))
    print(res.warnings, res.info.get("gas_temperature_check"))
    w = [d for d in res.warnings if d.code == "gas-temperature-suspect"]
    assert w and w[0].data["evidence"] == "plume rise" and w[0].data["direction"] == "high"
    assert w[0].data["bias_factor"] > 1.3


@pytest.mark.parametrize("with_exit", [False, True])
def test_hot_gas_warning_is_silent_on_the_ambient_preset(ambient, with_exit):
    surf, source = _lab_surfaces(ambient)
    exit_K = synth.preset_release("lab-ch4-5slpm-gf320").exit_temperature_K if with_exit else None
    res = quantify(ambient, surf, QuantifyConfig(source=source, exit_temperature_K=exit_K))
    print(res.warnings, res.info.get("gas_temperature_check"))
    assert not res.warnings.has("gas-temperature-suspect")


# -- the background ---------------------------------------------------------------


def test_auto_background_leaves_strips_the_gas_visits():
    rng = np.random.default_rng(0)
    t, h, w = 40, 60, 60
    frames = 10.0 + 0.01 * rng.standard_normal((t, 1, h, w))
    surf = Surface([(20, 30), (40, 30)], name="S")
    xy, n, dl = surf.samples(step_px=1.0)
    tt = (np.arange(len(xy)) + 0.5) / len(xy)
    samples = [(xy, n, dl, tt)]
    clean = choose(frames, [surf], samples, np.array([1.0]))
    assert clean["method"] == "beside-surface", clean["reason"]
    # Puffs of gas (+0.1, 10x the noise) cross the right-hand strip in a
    # third of the frames.
    gassy = frames.copy()
    gassy[::3, :, 25:35, 40:50] += 0.1
    dirty = choose(gassy, [surf], samples, np.array([1.0]))
    assert dirty["method"] == "percentile", dirty["reason"]
    assert "carry gas" in dirty["reason"]


# -- record length ------------------------------------------------------------------


def test_record_length_for_a_ten_percent_mean_of_white_noise():
    rng = np.random.default_rng(1)
    n, rate_hz = 400, 10.0
    series = 1.0 + 1.0 * rng.standard_normal(n)  # sd / mean = 1, independent frames
    a = budget.record_length_advice(series, rate_hz, float(n), speed_m_s=1e6, width_m=1.0)
    # sd/mean / sqrt(N) = 0.1 needs N = 100 frames = 10 s.
    assert a["needed_s"] == pytest.approx(10.0, rel=0.25)
    assert a["record_s"] == pytest.approx(40.0)


def test_record_length_advice_on_a_short_record(ambient):
    surf, source = _lab_surfaces(ambient)
    res = quantify(ambient, surf, QuantifyConfig(source=source, frames=(0, 12)))
    adv = res.info["record_length"]["CH4"]
    print(adv)
    assert adv["record_s"] == pytest.approx(12 / 15)
    assert adv["needed_s"] > adv["record_s"]
    assert res.warnings.has("record-too-short")
    assert "record-too-short" in res.summary()


# -- a speed nobody measured ----------------------------------------------------


def test_a_surface_whose_speed_is_zero_everywhere_has_an_unbounded_interval_not_zero(
    ambient, monkeypatch, tmp_path
):
    # A flow that found no motion anywhere (as at 68 px per frame: 1 g/h in a
    # 2 m/s wind at 1.5 m, 15 Hz, the envelope's default grid): the rate
    # read 0 with an interval [0, 0] and no detection limit, "0 kg/h" of a
    # plume nobody measured. Nothing bounds it then.
    import json
    import math

    from qogi.pipeline import velocity

    real = velocity.block_velocity

    def still(*a, **k):
        f = real(*a, **k)
        return None if f is None else f._replace(u=0 * f.u, v=0 * f.v, reverse_speed=None)

    monkeypatch.setattr(velocity, "block_velocity", still)
    surf, source = _lab_surfaces(ambient)
    truth = ambient.truth.emission_rate_kg_s["CH4"] * 3600
    res = quantify(ambient, surf, QuantifyConfig(source=source))
    print(res.summary())
    assert res.complete
    for s in res.surfaces:
        r = s.species["CH4"]
        lo, hi = r.ci90_kg_h
        assert math.isinf(hi) and lo <= 0.0 <= truth
        assert r.detected is None and r.upper_limit_kg_h is None
        assert "speed not measured" in r.text() and "unbounded" in r.text()
        assert res.warnings.has("speed-not-measured")
        assert any(
            w.code == "speed-not-measured" and w.surface == s.surface.name for w in res.warnings
        )
    assert "speed not measured" in res.summary()
    res.to_json(tmp_path / "r.json")
    doc = json.loads((tmp_path / "r.json").read_text())
    assert all(s["species"]["CH4"]["ci90_kg_h"][1] is None for s in doc["surfaces"])
    res.plot(tmp_path / "r.png")  # an unbounded band is not drawn, not an error


def _crosswind_gram_per_hour(tmp_path, duration_s, seed, surfaces_px, width, height):
    """The envelope's 1 g/h at 1.5 m in a 2 m/s wind over the sky (68 px per
    15 Hz frame), rendered and quantified with the defaults and the source."""
    from qogi.apps import envelope

    grid = tmp_path / "grid.toml"
    grid.write_text(
        "[base]\nrate_kg_h = 0.001\ndistance_m = 1.5\ncontrast_K = 9.3\nwind_m_s = 2.0\n"
        f'background = "sky"\ncamera = "gf320"\nduration_s = {duration_s}\nseed = [{seed}]\n'
        f"surfaces_px = [{surfaces_px}]\nwidth_px = {width}\nheight_px = {height}\n"
    )
    (cell,) = envelope.load_grid(grid).cells
    envelope.render_cell(cell, tmp_path / "c.h5")
    lines, source = envelope.surfaces(cell)
    rec = qogi.open_recording(tmp_path / "c.h5")
    res = quantify(rec, [[(a, b), (c, d)] for a, b, c, d in lines], QuantifyConfig(source=source))
    print(res.summary())
    return res


@pytest.mark.slow
def test_a_plume_faster_than_the_flow_tracks_is_not_given_a_bound_below_its_truth(tmp_path):
    # 1 g/h in a 2 m/s wind at 1.5 m (68 px per 15 Hz frame): the flow reads a
    # tenth of the speed, the limit with it, and the result said "not
    # detected, < 0.045 g/h" of the 1 g/h truth. The self-checks find the
    # speed not measured (transport-unresolved): no bound then.
    import math

    res = _crosswind_gram_per_hour(tmp_path, 2.0, 0, "20, 30", 96, 72)
    assert res.warnings.has("transport-unresolved")
    for s in res.surfaces:
        r = s.species["CH4"]
        lo, hi = r.ci90_kg_h
        assert lo <= r.truth_kg_h <= hi, (s.surface.name, r.ci90_kg_h)
        if r.detected is False:  # a stated bound must hold
            assert r.upper_limit_kg_h >= r.truth_kg_h
        if math.isinf(hi):
            assert res.warnings.has("no-bound-without-speed") or res.warnings.has(
                "speed-not-measured"
            )
    assert res.warnings.has("no-bound-without-speed")


@pytest.mark.slow
def test_a_plume_too_faint_for_the_flow_is_not_given_a_bound_from_the_speed_it_read(tmp_path):
    # The same scene, 3 s of 160 x 120 at seed 4 (the envelope's held-out
    # seeds): the flow read 0.02 m/s (0.6 px per frame, below its 1 px
    # range; no speed self-check failed, the flow reversed) and the result
    # said "not detected, < 0.12 g/h" of the 1 g/h truth. A speed below the
    # flow's range is not a measurement: no bound then.
    res = _crosswind_gram_per_hour(tmp_path, 3.0, 4, "30, 45, 60", 160, 120)
    slow = [
        w for w in res.warnings if w.code == "no-bound-without-speed" and "1 px range" in w.message
    ]
    assert slow, [w.code for w in res.warnings]
    for s in res.surfaces:
        r = s.species["CH4"]
        if r.detected is False:  # a stated bound must hold
            assert r.upper_limit_kg_h >= r.truth_kg_h, (s.surface.name, r.text())
        assert r.ci90_kg_h[1] >= r.truth_kg_h
