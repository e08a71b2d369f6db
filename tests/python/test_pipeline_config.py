"""QuantifyConfig is held by role (scene conditions, methods, execution,
record) but
built, read, saved and loaded through the same flat keys as before: settings
files, result JSONs and batch tables written by earlier versions still load."""

from __future__ import annotations

import copy
import pickle

import pytest

import qogi
from qogi.pipeline import Execution, Methods, QuantifyConfig, SceneConditions
from qogi.pipeline.surfaces import Region

#: A result JSON's "config" as the flat dataclass wrote it (every key, its order).
OLD_FLAT = {
    "species": ["CH4", "CO2"],
    "gas_temperature": "infer",
    "velocity": "fluid",
    "wind_speed_m_s": None,
    "exit_velocity_m_s": None,
    "averaging": "per-frame",
    "background": {"x0": 1, "y0": 2, "x1": 30, "y1": 40},
    "background_percentile": 5.0,
    "source": [159.5, 227.0],
    "distance_m": 1.5,
    "ambient_temperature_K": 293.0,
    "pressure_Pa": None,
    "sigma_m": None,
    "frames": [0, 40],
    "num_threads": 2,
    "composition": {"CH4": 0.5, "CO2": 0.5},
    "column_density": "inversion",
    "velocity_systematic": None,
    "column_systematic": 0.1,
    "flux_level": True,
    "pair_stride": None,
    "block_frames": 64,
    "line_shape": "fixed:25+self",
    "exit_temperature_K": 363.0,
}


#: Keys added since (the audit record's settings, issue 28): after the old
#: ones, None when an old file does not give them.
ADDED = ["site", "component", "operator", "location"]


def test_an_old_flat_dict_loads_and_writes_back_the_same_keys_in_the_same_order():
    cfg = QuantifyConfig.from_dict(OLD_FLAT)
    d = cfg.to_dict()
    assert list(d) == list(OLD_FLAT) + ADDED
    assert all(d[k] is None for k in ADDED)
    assert d["background"] == OLD_FLAT["background"]
    assert d["source"] == (159.5, 227.0) and d["frames"] == (0, 40)
    assert QuantifyConfig.from_dict(d) == cfg


def test_flat_keys_land_in_their_role():
    cfg = QuantifyConfig(
        species="CO2",
        velocity="wind",
        wind_speed_m_s=3.0,
        num_threads=2,
        background=Region(0, 0, 10, 10),
        distance_m=12.0,
    )
    assert isinstance(cfg.conditions, SceneConditions)
    assert cfg.conditions.species == ["CO2"] and cfg.conditions.wind_speed_m_s == 3.0
    assert cfg.conditions.distance_m == 12.0
    assert isinstance(cfg.methods, Methods) and cfg.methods.velocity == "wind"
    assert cfg.methods.given_speed and cfg.methods.region_background
    assert isinstance(cfg.execution, Execution) and cfg.execution.num_threads == 2
    # Flat reads and writes go to the role's object.
    cfg.source = (4.0, 5.0)
    assert cfg.conditions.source == (4.0, 5.0) and cfg.source == (4.0, 5.0)


def test_parts_build_the_same_config_as_flat_keys():
    flat = QuantifyConfig(
        species=["CH4"], gas_temperature=320.0, averaging="time-averaged", frames=(2, 9)
    )
    parts = QuantifyConfig.from_parts(
        SceneConditions(species=["CH4"], gas_temperature=320.0),
        Methods(averaging="time-averaged"),
        Execution(frames=(2, 9)),
    )
    assert parts == flat and parts.to_dict() == flat.to_dict()


def test_checks_still_run_within_and_across_roles():
    with pytest.raises(ValueError, match="gas_temperature"):
        QuantifyConfig(gas_temperature=900.0)
    with pytest.raises(ValueError, match="averaging"):
        QuantifyConfig(averaging="sometimes")
    with pytest.raises(ValueError, match="block_frames"):
        QuantifyConfig(block_frames=3)
    with pytest.raises(ValueError, match="wind_speed_m_s"):
        QuantifyConfig(velocity="wind", wind_speed_m_s=0.0)
    # A method that needs a scene fact: given, or the recording's (issue 27),
    # else refused when the run starts (before any work).
    windless = qogi.Scene(distance_m=3.0, ambient_temperature_K=290.0, pressure_Pa=1e5)
    with pytest.raises(ValueError, match="wind_speed_m_s must be given for velocity='wind'"):
        QuantifyConfig(velocity="wind").completed(windless)
    with pytest.raises(TypeError, match="no_such_key"):
        QuantifyConfig(no_such_key=1)


def test_replace_copy_and_pickle_keep_every_setting_and_the_original_unchanged():
    cfg = QuantifyConfig.from_dict(OLD_FLAT)
    other = cfg.replace(num_threads=1, background="percentile")
    assert other.num_threads == 1 and other.background == "percentile"
    assert cfg.num_threads == 2 and isinstance(cfg.background, Region)
    for c in (copy.copy(cfg), copy.deepcopy(cfg), pickle.loads(pickle.dumps(cfg))):
        assert c == cfg and c is not cfg
        c.num_threads = 7
        assert cfg.num_threads == 2
    assert QuantifyConfig.field_names() == list(OLD_FLAT) + ADDED


def test_toml_round_trip(tmp_path):
    cfg = QuantifyConfig.from_dict(OLD_FLAT)
    cfg.to_toml(tmp_path / "s.toml")
    assert QuantifyConfig.from_toml(tmp_path / "s.toml") == cfg
