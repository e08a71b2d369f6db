"""Every setting of the run is declared once (qogi.pipeline.settings), and every way
in reads it from there: the command line, a saved-settings TOML, a batch
manifest (CSV and TOML) accept the same values and refuse the same ones with
the same message (the viewer's form: tests/gui/test_settings_form.py). The
docs' settings table is the generated one, and a scene fact the recording
holds completes the config (issue 27)."""

from __future__ import annotations

import contextlib
import dataclasses
import io
import json
import pathlib
import subprocess
import sys

import pytest

import qogi
from qogi.apps import batch, cli
from qogi.errors import UsageError
from qogi.pipeline import QuantifyConfig, settings
from qogi.pipeline.config import load_settings

ROOT = pathlib.Path(__file__).resolve().parents[2]

#: Per setting: values accepted and refused, each as typed on a command line
#: or in a CSV cell (the TOML files get the same value as TOML writes it).
CASES = {
    "species": (["CH4", "CH4,CO2"], ["XYZ", "CH4,Q9"]),
    "gas_temperature": (["ambient", "infer", "320", "150"], ["700", "149.9", "hot", "nan"]),
    "velocity": (["fluid", "horn-schunck", "piv"], ["sideways", "optical"]),
    "wind_speed_m_s": (["3", "100"], ["0", "-1", "100.5", "fast"]),
    "exit_velocity_m_s": (["12.5"], ["0", "600"]),
    "averaging": (["per-frame", "time-averaged"], ["sometimes"]),
    "background": (["auto", "beside-surface", "percentile", "10,10,40,40"], ["sky", "1,2,3"]),
    "background_percentile": (["0", "50", "5"], ["51", "-1", "x"]),
    "source": (["159.5,227"], ["5", "a,b", "nan,1"]),
    "distance_m": (["12", "0.001"], ["0", "-2", "1e6", "inf"]),
    "ambient_temperature_K": (["295"], ["400", "100"]),
    "pressure_Pa": (["90000"], ["1e6", "10"]),
    "sigma_m": (["0.05"], ["0", "11"]),
    "frames": (["0:10", "2:9"], ["5:2", "5", "-1:4", "a:b"]),
    "num_threads": (["0", "4"], ["-3", "1.5", "many"]),
    "composition": (["CH4=1"], ["CH4=0", "CH4"]),
    "column_density": (["inversion", "truth"], ["guess"]),
    "velocity_systematic": (["0.1", "0"], ["1.5", "-0.1"]),
    "column_systematic": (["0.05"], ["2"]),
    "flux_level": (["true", "false"], ["maybe"]),
    "pair_stride": (["1", "100"], ["0", "101", "2.5"]),
    "block_frames": (["8", "450"], ["7", "8.5"]),
    "line_shape": (["hapi+air", "fixed:30+self", "fixed"], ["lorentz", "fixed:0.5", "hapi+none"]),
    "exit_temperature_K": (["328.15"], ["1000", "100"]),
    "site": (["Compressor station 7", "Ölfeld Nord"], ["x" * 201, "a\tb"]),
    "component": (["valve V-102"], ["x" * 201]),
    "operator": (["J. Doe"], ["line\tbreak"]),
    "location": (["52.1234 N, 4.5678 E"], ["x" * 300]),
}


def test_every_setting_has_cases_and_the_config_is_the_table():
    assert set(CASES) == set(settings.SETTINGS) == set(QuantifyConfig.field_names())
    assert list(settings.SETTINGS) == QuantifyConfig.field_names()
    for name, s in settings.SETTINGS.items():
        assert s.help and s.role in settings.ROLES and s.flag, name
        assert QuantifyConfig.default(name) == settings.default(name), name


def test_defaults_owned_elsewhere_are_read_from_their_owner():
    from qogi.measure import velocimetry
    from qogi.physics.forward import LineShape

    assert settings.default("velocity") == velocimetry.DEFAULT_METHOD == QuantifyConfig().velocity
    assert settings.default("line_shape") == str(LineShape()) == QuantifyConfig().line_shape
    # The velocity sources are qogi.measure.velocimetry's methods and the given speeds.
    assert settings.choices("velocity") == tuple(velocimetry.METHODS) + ("wind", "exit")


def test_scene_ranges_lie_within_the_recording_contract():
    """A value the config accepts is one a recording may hold."""
    from qogi.contract import RANGES

    for name, s in settings.SETTINGS.items():
        key = f"scene.{s.scene_key}"
        if key in RANGES and s.lo is not None:
            lo, hi, _, mode = RANGES[key]
            assert s.lo >= lo and s.hi <= hi, name
            assert not (s.lo == lo and mode == "exclusive_low" and not s.lo_open), name


def _body(name, text):
    """The table's message for a refused value ("" when accepted)."""
    try:
        settings.from_text(name, text)
    except settings.SettingError as e:
        return e.body if e.name == name else f"named {e.name}, not {name}"
    return ""


def _toml_value(name, text):
    """``text`` as a TOML value: a number, boolean or word as TOML writes
    it, the rest as a string (read as the CSV cell is)."""
    kind = settings.SETTINGS[name].kind
    try:
        if kind in ("float", "int", "gas_temperature") and text not in ("nan", "inf"):
            float(text)
            return text
    except ValueError:
        pass
    if kind == "bool" and text in ("true", "false"):
        return text
    return json.dumps(text)


REC = "rec.h5"
SURFACE = "1,2,3,4"


def _cli(tmp_path, name, text):
    """(accepted, stderr) of ``qogi quantify`` parsing FLAG TEXT and
    building the config (no run)."""
    from qogi.apps._cli_quantify import _config_from_args

    flag = settings.SETTINGS[name].flag
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err):
            args = cli.build_parser().parse_args(["quantify", REC, f"{flag}={text}"])
    except SystemExit as e:
        return False, f"exit {e.code}: {err.getvalue()}"
    try:
        _config_from_args(args)
    except UsageError as e:
        return False, str(e)
    return True, ""


def _outcome(load, path):
    """(accepted, message) of reading ``path`` with ``load``."""
    try:
        load(path)
    except UsageError as e:
        return False, str(e)
    return True, ""


def _settings_toml(tmp_path, name, text):
    p = tmp_path / "s.toml"
    p.write_text(f"{name} = {_toml_value(name, text)}\n")
    return _outcome(load_settings, p)


def _manifest(path):
    return batch.load_manifest(path, check_files=False)


def _manifest_csv(tmp_path, name, text):
    p = tmp_path / "m.csv"
    p.write_text(f'path,surfaces,{name}\n{REC},"{SURFACE}","{text}"\n')
    return _outcome(_manifest, p)


def _manifest_toml(tmp_path, name, text):
    p = tmp_path / "m.toml"
    p.write_text(
        f'[[recording]]\npath = "{REC}"\nsurfaces = "{SURFACE}"\n'
        f"{name} = {_toml_value(name, text)}\n"
    )
    return _outcome(_manifest, p)


WAYS = {
    "command line": _cli,
    "settings TOML": _settings_toml,
    "manifest CSV": _manifest_csv,
    "manifest TOML": _manifest_toml,
}


@pytest.mark.parametrize(
    "name, text, ok",
    [(n, t, True) for n, (good, _) in CASES.items() for t in good]
    + [(n, t, False) for n, (_, bad) in CASES.items() for t in bad],
)
@pytest.mark.parametrize("way", list(WAYS))
def test_each_way_in_accepts_and_refuses_the_same_with_the_same_message(
    tmp_path, name, text, ok, way
):
    body = _body(name, text)
    assert (body == "") is ok, body
    accepted, message = WAYS[way](tmp_path, name, text)
    if name in batch._RESERVED and way.startswith("manifest"):
        # qogi batch sets the thread count per worker: any value is refused.
        assert not accepted and "set by qogi batch" in message
        return
    assert accepted is ok, message
    if not ok:
        assert body in message, (way, message)
        assert "Traceback" not in message


def test_a_manifest_takes_line_shape_and_background_auto(tmp_path):
    """Issue 27: both used to be read as numbers and refused."""
    p = tmp_path / "m.csv"
    p.write_text(f'path,surfaces,line_shape,background\n{REC},"{SURFACE}",hapi+air,auto\n')
    [row] = batch.load_manifest(p, check_files=False)
    assert row.config.line_shape == "hapi+air" and row.config.background == "auto"
    t = tmp_path / "m.toml"
    t.write_text(
        '[defaults]\nline_shape = "hapi+air"\nbackground = "auto"\n'
        f'[[recording]]\npath = "{REC}"\nsurfaces = "{SURFACE}"\n'
    )
    [row] = batch.load_manifest(t, check_files=False)
    assert row.config.line_shape == "hapi+air" and row.config.background == "auto"


def test_a_saved_config_reads_back_equal_through_every_file(tmp_path):
    cfg = QuantifyConfig(
        species=["CH4", "CO2"],
        gas_temperature=320.0,
        velocity="dis",
        background=qogi.Region(1, 2, 30, 40),
        frames=(2, 9),
        composition={"CH4": 0.5, "CO2": 0.5},
        line_shape="hapi+air",
        pair_stride=2,
        flux_level=False,
    )
    cfg.to_toml(tmp_path / "s.toml")
    assert QuantifyConfig.from_toml(tmp_path / "s.toml") == cfg
    # The same keys as a manifest's [defaults] (qogi batch sets the threads).
    body = "\n".join(
        ln for ln in (tmp_path / "s.toml").read_text().splitlines() if "num_threads" not in ln
    )
    (tmp_path / "m.toml").write_text(
        f"[defaults]\n{body}\n[[recording]]\npath = '{REC}'\nsurfaces = '{SURFACE}'\n"
    )
    [row] = batch.load_manifest(tmp_path / "m.toml", check_files=False)
    assert row.config == cfg


def test_the_docs_settings_table_is_the_generated_one():
    done = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "settings_table.py"), "--check"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stdout + done.stderr
    page = (ROOT / "docs" / "pipeline_api.md").read_text()
    assert settings.markdown_table() in page
    for name in settings.SETTINGS:
        assert f"| `{name}` |" in page


def test_quantify_help_has_no_doubled_percent_and_the_exit_codes_stand_apart(capsys):
    with pytest.raises(SystemExit):
        cli.main(["quantify", "--help"])
    out = capsys.readouterr().out
    assert "%%" not in out and "90% interval" in out
    example, _, codes = out.partition("exit status:")
    assert codes and example.rstrip().endswith("out.png")
    assert example.endswith("\n\n")


# -------------------------------------------------- the recording completes


def _scene(**kw):
    base = dict(distance_m=3.0, ambient_temperature_K=290.0, pressure_Pa=101325.0)
    return qogi.Scene(**{**base, **kw})


def test_a_scene_fact_not_given_is_the_recordings_and_a_given_one_wins():
    scene = _scene(gas_temperature_K=320.0, wind_speed_m_s=4.0, species=("CO2",))
    cfg, taken = QuantifyConfig(velocity="wind").completed(scene)
    assert cfg.wind_speed_m_s == 4.0 and cfg.species == ["CO2"] and cfg.distance_m == 3.0
    # The recording's gas temperature is its source's: shown, never assumed
    # for the plume at the surfaces (docs/recording.md).
    assert cfg.gas_temperature == "ambient"
    assert taken == {
        "species": ["CO2"],
        "wind_speed_m_s": 4.0,
        "distance_m": 3.0,
        "ambient_temperature_K": 290.0,
        "pressure_Pa": 101325.0,
    }
    given = QuantifyConfig(
        velocity="wind", wind_speed_m_s=2.0, gas_temperature="ambient", species=["CH4"]
    )
    cfg, taken = given.completed(scene)
    assert (cfg.gas_temperature, cfg.wind_speed_m_s, cfg.species) == ("ambient", 2.0, ["CH4"])
    assert set(taken) == {"distance_m", "ambient_temperature_K", "pressure_Pa"}
    # The recording's wind is used only for velocity="wind".
    cfg, taken = QuantifyConfig().completed(scene)
    assert cfg.wind_speed_m_s is None and "wind_speed_m_s" not in taken


def test_a_scene_without_the_fact_falls_back_or_says_what_to_give():
    cfg, taken = QuantifyConfig().completed(_scene())
    assert cfg.gas_temperature == "ambient" and cfg.species == ["CH4"]
    assert "gas_temperature" not in taken and "species" not in taken
    with pytest.raises(UsageError, match=r"wind_speed_m_s must be given for velocity='wind'"):
        QuantifyConfig(velocity="wind").completed(_scene())
    with pytest.raises(
        UsageError,
        match=r"recording's /scene wind_speed_m_s must be within \(0, 100\] m/s; got 0: give",
    ):
        QuantifyConfig(velocity="wind").completed(_scene(wind_speed_m_s=0.0))


def _windy_recording(path, **scene):
    """A small recording (tests/python/test_interrupt.py's) whose /scene
    holds the given facts."""
    from test_interrupt import small_recording

    small_recording(path)
    with qogi.open_recording(path) as rec:
        frames, camera = rec.frames(quantity="radiance"), rec.camera
        sc = dataclasses.replace(rec.scene, **scene)
    qogi.Recording.from_arrays(frames, quantity="radiance", camera=camera, scene=sc).save(path)
    return path


def test_quantify_takes_the_recordings_wind_and_says_so(tmp_path):
    path = _windy_recording(tmp_path / "w.h5", wind_speed_m_s=2.5, gas_temperature_K=300.0)
    rec = qogi.open_recording(path)
    surface = [qogi.Surface([(4, 12), (28, 12)])]
    res = qogi.quantify(rec, surface, QuantifyConfig(velocity="wind"))
    assert res.info["from_recording"]["wind_speed_m_s"] == 2.5
    assert "gas_temperature" not in res.info["from_recording"]
    assert res.config.wind_speed_m_s is None  # the config as given
    given = QuantifyConfig(
        velocity="wind", wind_speed_m_s=2.5, gas_temperature="ambient", species=["CH4"]
    )
    same = qogi.quantify(rec, surface, given)
    assert same.total("CH4").mean_kg_h == res.total("CH4").mean_kg_h
    assert "wind_speed_m_s" not in same.info["from_recording"]
    # A given value wins over the recording's.
    other = qogi.quantify(rec, surface, QuantifyConfig(velocity="wind", wind_speed_m_s=5.0))
    assert other.total("CH4").mean_kg_h == pytest.approx(2 * res.total("CH4").mean_kg_h)


def test_a_manifest_row_with_wind_and_no_speed_needs_it_in_the_recording(tmp_path):
    _windy_recording(tmp_path / "w.h5", wind_speed_m_s=2.5)
    _windy_recording(tmp_path / "calm.h5")
    (tmp_path / "m.csv").write_text(
        f'path,surfaces,velocity\nw.h5,"{SURFACE}",wind\ncalm.h5,"{SURFACE}",wind\n'
    )
    with pytest.raises(UsageError, match=r"line 3: column 'wind_speed_m_s': must be given"):
        batch.load_manifest(tmp_path / "m.csv")
    (tmp_path / "m.csv").write_text(f'path,surfaces,velocity\nw.h5,"{SURFACE}",wind\n')
    [row] = batch.load_manifest(tmp_path / "m.csv")
    assert row.config.velocity == "wind" and row.config.wind_speed_m_s is None
