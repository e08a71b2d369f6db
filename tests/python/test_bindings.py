"""Every options class of the engine is bound by one pattern (cpp/bindings/common.h):
keyword constructor with the struct's defaults, checked on entry, repr naming the
class, to_dict, equality and pickling that carry every field."""

import pickle
import re

import numpy as np
import pytest

from qogi import _engine

#: One non-default value per options class: the round trips must carry it (a
#: pickle or dict that fell back to the defaults would not compare equal).
CHANGED = {
    "AbsorberTableOptions": dict(
        temperatures_K=[250.0, 300.0], wing_cm1=0.0, wing_half_widths=50.0
    ),
    "AtmosphericPath": dict(distance_m=120.0, relative_humidity=0.3),
    "BinnedModelOptions": dict(key_temperatures_K=[260.0, 400.0], num_nodes=65),
    "CalibrationOptions": dict(quadratic=True, saturation_counts=16383.0),
    "CameraModel": dict(
        name="test",
        width=64,
        height=48,
        channels=[
            _engine.SpectralResponse(np.array([2900.0, 3100.0]), np.array([1.0, 1.0]), "band")
        ],
    ),
    "CountsFluxCurve": dict(gain=2.5, offset=-3.0, quadratic=1e-4),
    "CrossSectionOptions": dict(wing_half_widths=0.0, wing_cm1=25.0, line_shift=False),
    "DisOptions": dict(patch_size=12),
    "DriftOptions": dict(long_lag=20, max_pairs=7),
    "DriftingBackgroundOptions": dict(percentile=10.0, window_s=2.0, iterations=2),
    "ExactModelOptions": dict(num_nodes=101, richardson=False),
    "FarnebackOptions": dict(winsize=21, gaussian_window=False),
    "FluidFlowOptions": dict(alpha=0.5, finest_level=0),
    "GasConditions": dict(temperature_K=350.0, self_fraction=0.2),
    "HornSchunckOptions": dict(alpha=0.7),
    "InversionOptions": dict(
        fractions=[_engine.ParameterSpec(_engine.ParameterMode.free, 1e-3, 0.0, 0.0, 1.0)],
        netd_K=[0.02, 0.03],
        solver=_engine.SolverKind.table,
    ),
    "LucasKanadeOptions": dict(window_sigma=2.0),
    "MedianTestOptions": dict(threshold=3.0),
    "ParameterSpec": dict(mode=_engine.ParameterMode.prior, value=400.0, prior_sigma=20.0),
    "PivOptions": dict(window_size=32, deform=False),
    "PlumeMaskOptions": dict(min_area=5),
    "RegistrationOptions": dict(rotation=False, max_iterations=12, robust_scale=3.0),
    "SceneTableOptions": dict(ambient_temperature_K=290.0, temperature_step_K=2.0),
    "SynthModelOptions": dict(seed=7, modes_per_band=6),
    "SynthRelease": dict(rate=2.0, rate_unit="kg/h", composition={"CH4": 0.9, "CO2": 0.1}),
    "SynthView": dict(width_px=64, projection="perspective"),
    "TemporalFilterOptions": dict(statistic=_engine.TemporalStatistic.mean, window=7),
}


def _options_classes():
    return sorted(
        name
        for name, obj in vars(_engine).items()
        if isinstance(obj, type) and isinstance(getattr(obj, "fields", None), tuple)
    )


def _same(a, b) -> bool:
    """Field values equal; spectral responses (no ==) by their samples and name."""
    if isinstance(a, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, _engine.SpectralResponse):
        return (
            a.name == b.name
            and np.array_equal(a.nu_cm1, b.nu_cm1)
            and np.array_equal(a.response, b.response)
        )
    return a == b


def test_every_options_class_has_an_example_here():
    assert _options_classes() == sorted(CHANGED)


@pytest.mark.parametrize("name", sorted(CHANGED))
def test_options_round_trip_through_pickle_and_dict_with_every_field(name):
    cls = getattr(_engine, name)
    o = cls(**CHANGED[name])
    d = o.to_dict()
    assert tuple(d) == cls.fields
    for key, value in CHANGED[name].items():
        assert _same(d[key], value), key
    for back in (pickle.loads(pickle.dumps(o)), cls(**d)):
        assert type(back) is cls
        assert all(_same(back.to_dict()[k], v) for k, v in d.items())
        if name != "CameraModel":  # its SpectralResponse channels compare by identity
            assert back == o
    assert repr(o).startswith(name + "(")
    for field in cls.fields:
        assert field + "=" in repr(o)


#: Strings that stand for enums in the engine: another valid name.
OTHER_NAME = {"kg/h": "g/h", "perspective": "orthographic"}


def _other(v):
    """A value of the same type that differs from v."""
    if hasattr(type(v), "__members__"):  # an engine enum
        return type(v)(0 if int(v) else 1)
    if isinstance(v, bool):
        return not v
    if isinstance(v, (int, float)):
        return v + 1
    if isinstance(v, str):
        return OTHER_NAME.get(v, v + "x")
    if isinstance(v, list):
        return v + v[:1]
    if isinstance(v, dict):
        return {**v, "H2O": 0.0}
    raise TypeError(type(v))


@pytest.mark.parametrize("name", sorted(CHANGED))
def test_options_reject_unknown_names_and_differ_in_any_field(name):
    cls = getattr(_engine, name)
    with pytest.raises(TypeError, match=f"{name} has no field 'no_such_field'"):
        cls(**CHANGED[name], no_such_field=1)
    o = cls(**CHANGED[name])
    assert o != object()
    for key, value in CHANGED[name].items():
        other = pickle.loads(pickle.dumps(o))
        setattr(other, key, _other(value))  # attributes are writable
        assert not _same(getattr(other, key), value), key
        if name != "CameraModel":
            assert other != o, key


@pytest.mark.parametrize(
    "name,bad,message",
    [
        ("SceneTableOptions", dict(temperature_step_K=0.5), "temperature_step_K"),
        ("ExactModelOptions", dict(num_nodes=2), "num_nodes"),
        ("GasConditions", dict(temperature_K=-1.0), "temperature_K"),
        ("CalibrationOptions", dict(blackbody_emissivity=1.5), "blackbody_emissivity"),
        ("PivOptions", dict(window_size=15), "window_size"),
    ],
)
def test_options_out_of_range_raise_value_error_naming_the_field(name, bad, message):
    with pytest.raises(ValueError, match=message):
        getattr(_engine, name)(**bad)


def test_positional_arguments_keep_their_order_where_they_were_accepted():
    c = _engine.GasConditions(350.0, 5e4, 0.25)
    assert (c.temperature_K, c.pressure_Pa, c.self_fraction) == (350.0, 5e4, 0.25)
    p = _engine.ParameterSpec(_engine.ParameterMode.free, 1.0, 0.0, 0.5, 2.0)
    assert (p.mode, p.value, p.lower, p.upper, p.tied_to) == (
        _engine.ParameterMode.free,
        1.0,
        0.5,
        2.0,
        -1,
    )
    with pytest.raises(TypeError):
        _engine.CalibrationOptions(True)  # keyword-only, as before


def test_defaults_are_the_engine_structs_and_shown_in_the_signature():
    o = _engine.SceneTableOptions()
    assert (o.ambient_temperature_K, o.temperature_step_K, o.nodes_per_decade) == (296.0, 5.0, 8)
    assert re.search(
        r"temperature_step_K: [\w.]+ = 5\.0,", _engine.SceneTableOptions.__init__.__doc__
    )
