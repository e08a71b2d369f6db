"""The viewer's analysis form reads the run's settings table (qogi.pipeline.settings):
for every setting it shows, it accepts what the run accepts and refuses the
rest with the table's own message (the message of the command line, the
settings TOML and the batch manifest: tests/python/test_settings.py); its
choices and hints are the table's (issue 27)."""

from __future__ import annotations

import pytest

from qogi.pipeline import settings
from qogi_gui.settings import AVERAGING, BACKGROUNDS, AnalysisSettings, velocity_choices

#: Setting -> (form field, the form's other fields that make it count).
ON_THE_FORM = {
    "gas_temperature": ("gas_temperature_K", {"gas_temperature_mode": "given"}),
    "wind_speed_m_s": ("wind_speed_m_s", {"velocity": "wind"}),
    "exit_velocity_m_s": ("exit_velocity_m_s", {"velocity": "exit"}),
    "background_percentile": ("background_percentile", {"background": "percentile"}),
    "distance_m": ("distance_m", {}),
    "ambient_temperature_K": ("ambient_temperature_K", {}),
    "pressure_Pa": ("pressure_Pa", {}),
    "sigma_m": ("sigma_m", {}),
    "exit_temperature_K": ("exit_temperature_K", {}),
    "num_threads": ("num_threads", {}),
}
#: Settings the form offers as choices (checked against the table's), or
#: composes from several widgets (checked below).
CHOSEN = {"velocity", "averaging", "background", "species", "line_shape", "frames", "source"}
#: Settings the form does not offer (a run from the viewer takes their defaults).
NOT_ON_THE_FORM = {
    "composition",
    "column_density",
    "velocity_systematic",
    "column_systematic",
    "flux_level",
    "pair_stride",
    "block_frames",
    # The audit record's settings: qogi quantify's options and manifest columns.
    "site",
    "component",
    "operator",
    "location",
}


def test_every_setting_is_accounted_for():
    assert set(ON_THE_FORM) | CHOSEN | NOT_ON_THE_FORM == set(settings.SETTINGS)
    assert not (set(ON_THE_FORM) & CHOSEN) and not (CHOSEN & NOT_ON_THE_FORM)


def _cases():
    """Per number on the form: its bounds (accepted), just beyond them and a
    word (refused), from the table."""
    out = []
    for name in ON_THE_FORM:
        s = settings.SETTINGS[name]
        lo, hi = s.lo, s.hi
        integer = s.kind == "int"
        step = 1 if integer else (1e-6 * max(abs(lo), 1.0) if lo is not None else 1.0)
        if lo is not None:
            out.append((name, f"{lo + step if s.lo_open else lo:g}", True))
            out.append(
                (
                    name,
                    f"{lo if s.lo_open else lo - (step if integer else abs(lo) * 0.01 + 1e-3):g}",
                    False,
                )
            )
        if hi is not None:
            out.append((name, f"{hi:g}", True))
            out.append((name, f"{hi * 1.01 + 1:g}", False))
        out.append((name, "lots", False))
        out.append((name, "nan" if not integer else "2.5", False))
    return out


@pytest.mark.parametrize("name, text, ok", _cases())
def test_the_form_accepts_and_refuses_as_the_run_does_with_its_message(name, text, ok):
    field, others = ON_THE_FORM[name]
    form = AnalysisSettings(**others, **{field: text})
    message = form.validate(None)[field]
    try:
        settings.from_text(name, text)
        body = ""
    except settings.SettingError as e:
        body = e.body
    assert (body == "") is ok, (text, body)
    assert message == body


@pytest.mark.parametrize("start, stop", [("5", "2"), ("-1", "4"), ("3", "3"), ("0", "8")])
def test_the_form_checks_the_frame_range_as_the_run_does(start, stop):
    err = AnalysisSettings(frame_start=start, frame_stop=stop).validate(None)
    try:
        settings.from_text("frames", f"{start}:{stop}")
        body = ""
    except settings.SettingError as e:
        body = e.body
    assert (err["frame_start"] or err["frame_stop"]) == body


def test_a_non_finite_source_gets_the_runs_message():
    form = AnalysisSettings(use_source=True, source_x="nan", source_y="1")
    with pytest.raises(settings.SettingError) as e:
        settings.from_text("source", "nan,1")
    assert form.validate(None)["source"].startswith(e.value.body)


def test_the_forms_choices_and_hints_are_the_tables():
    assert settings.choices("averaging") == AVERAGING
    assert settings.choices("background") + ("region",) == BACKGROUNDS
    assert set(velocity_choices()) == set(settings.choices("velocity"))
    assert velocity_choices()[0] == settings.default("velocity")
    hints = AnalysisSettings().hints()
    assert hints["gas_temperature_K"] == "[150, 600] K"  # not the recording contract's 2500 K
    for name, (field, _) in ON_THE_FORM.items():
        assert settings.SETTINGS[name].range_text() in hints[field], name


def test_a_gas_temperature_the_run_refuses_is_refused_before_run():
    """Issue 27: the form used to accept up to 2500 K, the run refused > 600 K."""
    form = AnalysisSettings(gas_temperature_mode="given", gas_temperature_K="700")
    assert form.validate(None)["gas_temperature_K"] == "must be within [150, 600] K; got 700"
