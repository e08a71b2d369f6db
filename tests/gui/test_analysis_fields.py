"""The analysis form's line-shape rule and exit temperature (issue 18): each
reaches the run's config, a bad value is a message beside its field, the
form's bounds are the pipeline's, and the Results tab shows every budget term
(``line shape`` among them) and the run's warnings."""

from __future__ import annotations

import pytest
from test_viewmodel import run_to_end

import qogi
from qogi.physics.forward import LineShape
from qogi_gui import results
from qogi_gui.settings import AnalysisSettings


@pytest.fixture
def opened(vm, rec_path):
    assert vm.open(rec_path), vm.last_message
    assert vm.add_surface([(4, 12), (28, 12)], name="A")
    return vm


def _run(vm, **fields):
    errors = vm.update_settings(**fields)
    assert not any(errors.values()), errors
    assert vm.start_run(), vm.last_message
    run_to_end(vm)
    return vm


def test_the_defaults_are_the_pipelines(opened, api):
    _run(opened)
    [(_, cfg, _)] = api.calls
    assert cfg.line_shape == str(LineShape()) == qogi.QuantifyConfig().line_shape
    assert cfg.exit_temperature_K is None


def test_line_shape_and_exit_temperature_reach_the_run(opened, api):
    _run(opened, line_shape_wing="hapi", line_shape_broadening="air", exit_temperature_K="330")
    [(_, cfg, _)] = api.calls
    assert cfg.line_shape == "hapi+air" and cfg.exit_temperature_K == 330.0
    # The result's settings (report, JSON) are the run's.
    assert opened.result_settings["line_shape"] == "hapi+air"
    assert opened.result_settings["exit_temperature_K"] == 330.0
    # A fixed wing's width (not run: a new width means new cross-section tables).
    opened.update_settings(
        line_shape_wing="fixed",
        line_shape_wing_cm1="40",
        line_shape_broadening="self",
        exit_temperature_K="",
    )
    cfg = opened.settings.build_config(qogi, opened.recording)
    assert cfg.line_shape == "fixed:40+self" and cfg.exit_temperature_K is None


def test_bad_values_are_messages_beside_their_fields(opened, api):
    bad = opened.update_settings(exit_temperature_K="1000", line_shape_wing_cm1="0.5")
    assert bad["exit_temperature_K"] == "must be within [150, 900] K; got 1000"
    assert bad["line_shape_wing_cm1"] == (
        "'fixed:0.5+self': wing_cm1 must be within [1, 100] cm-1; got 0.5"
    )
    assert not opened.start_run()
    msg = opened.last_message
    assert msg.level == "error" and "exit temperature: must be within [150, 900] K" in msg.text
    assert "line wing half-width: 'fixed:0.5+self'" in msg.text
    assert opened.field_errors["exit_temperature_K"] and not api.calls
    bad = opened.update_settings(exit_temperature_K="hot", line_shape_wing_cm1="")
    assert "must be a number; got 'hot'" in bad["exit_temperature_K"]
    assert "empty" in bad["line_shape_wing_cm1"]
    # HAPI's rule has no fixed width: the width field is not checked then.
    bad = opened.update_settings(exit_temperature_K="", line_shape_wing="hapi")
    assert not any(bad.values()), bad
    bad = opened.update_settings(line_shape_wing="lorentz", line_shape_broadening="self")
    assert "fixed, hapi" in bad["line_shape"]
    bad = opened.update_settings(line_shape_wing="fixed", line_shape_broadening="none")
    assert "self, air" in bad["line_shape"]


@pytest.mark.parametrize(
    "value, ok", [(150.0, True), (900.0, True), (149.9, False), (900.1, False)]
)
def test_the_exit_temperature_bounds_are_the_configs(value, ok):
    form = AnalysisSettings(exit_temperature_K=f"{value:g}")
    assert (form.validate(None)["exit_temperature_K"] == "") is ok
    if ok:
        assert qogi.QuantifyConfig(exit_temperature_K=value).exit_temperature_K == value
    else:
        with pytest.raises(ValueError, match="exit_temperature_K"):
            qogi.QuantifyConfig(exit_temperature_K=value)


@pytest.mark.parametrize("value, ok", [(1.0, True), (100.0, True), (0.99, False), (100.5, False)])
def test_the_wing_width_bounds_are_the_line_shapes(value, ok):
    form = AnalysisSettings(line_shape_wing_cm1=f"{value:g}")
    assert (form.validate(None)["line_shape_wing_cm1"] == "") is ok
    if ok:
        assert LineShape.parse(form.line_shape()).wing_cm1 == value
    else:
        with pytest.raises(ValueError, match="wing_cm1"):
            LineShape.parse(f"fixed:{value:g}")


def test_results_show_every_budget_term_and_the_warnings():
    """The Results tab's rows: each budget term of each surface (the terms a
    surface lacks show as missing), and every warning with its code and where."""
    from types import SimpleNamespace as NS

    from qogi.diagnostics import Diagnostics

    def rate(terms):
        return NS(
            rate_kg_s=[1e-4, 2e-4],
            mean_kg_h=0.54,
            ci90_kg_h=(0.3, 0.8),
            uncertainty_terms_kg_h=terms,
            dominant_uncertainty=max(terms, key=terms.get),
        )

    res = NS(
        surfaces=[
            NS(surface=NS(name="A"), species={"CH4": rate({"temporal": 0.05, "line shape": 0.12})}),
            NS(
                surface=NS(name="B"),
                species={"CH4": rate({"temporal": 0.04, "line shape": 0.02, "background": 0.01})},
            ),
        ],
        warnings=Diagnostics(),
    )
    res.warnings.add(
        "gas-temperature-suspect", "the rate is likely too high by about x2.2", species="CH4"
    )
    res.warnings.add("flux-against-surface", "flux runs against the surface", surface="B")
    a, b = results.rate_rows(res)
    assert results.uncertainty_terms([a, b]) == ["temporal", "line shape", "background"]
    assert a.uncertainty_terms_kg_h == {"temporal": 0.05, "line shape": 0.12}
    assert a.dominant_uncertainty == "line shape" and b.dominant_uncertainty == "temporal"
    assert results.warning_lines(res) == [
        "[gas-temperature-suspect CH4] the rate is likely too high by about x2.2",
        "[flux-against-surface B] flux runs against the surface",
    ]
    assert results.warning_lines(NS(surfaces=[])) == []


def test_a_rate_not_detected_shows_the_bound_the_result_states():
    # The Results tab says what qogi.SpeciesRate.text says: "< X" with X the
    # larger of the limit and the interval's upper end (issue 28), not the limit.
    row = results.RateRow(
        surface="A",
        species="CH4",
        mean_kg_h=0.002,
        ci90_kg_h=(0.001, 0.006),
        mean_g_h=2.0,
        mean_slpm=0.05,
        truth_kg_h=None,
        n_frames=30,
        n_frames_valid=30,
        pixels_median=3.0,
        dominant_uncertainty="temporal",
        detection_limit_kg_h=0.004,
        detected=False,
        upper_limit_kg_h=0.006,
    )
    assert row.detection_text == "< 0.006 (not detected)"
    detected = results.RateRow(**{**row.__dict__, "detected": True, "upper_limit_kg_h": None})
    assert detected.detection_text == "0.004"
