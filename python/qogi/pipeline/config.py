"""The settings of a run, split by role.

:class:`QuantifyConfig` is what callers build, save and load: one flat set of
keys (docs/pipeline_api.md; the keys of settings files, result JSONs, batch
tables, the viewer's form and the command line). Inside it the settings are
four objects, each validating its own fields:

* :class:`SceneConditions`: facts about the scene and the gas that override
  or complete the recording's (the gas, its temperature and composition, the
  distance, ambient temperature and pressure, the source, the plume depth, a
  given wind or exit speed);
* :class:`Methods`: the analysis choices that change the result
  (velocimetry, background, averaging, column source, budget overrides, line
  shape, flux level);
* :class:`Execution`: how the run is carried out (which frames, threads,
  pair stride, streamed block length);
* :class:`Record`: who measured what, where (site, component, operator,
  location), carried into the result's audit record.

Each field is declared once, in the run's settings table
(:data:`qogi.pipeline.settings.SETTINGS`: role, type, unit, range or choices, default,
flag, help): the role objects check their fields with it, and the command
line, settings files, batch manifests, the viewer's form and the docs read
the same table. A scene fact not given is the recording's
(:meth:`QuantifyConfig.completed`, called by :func:`qogi.quantify`).

``QuantifyConfig(**flat)``, ``cfg.name`` (read and assignment),
:meth:`QuantifyConfig.to_dict` / :meth:`~QuantifyConfig.from_dict` and the TOML
round trip all use the flat keys, in the order of :data:`FIELDS`.
"""

from __future__ import annotations

import dataclasses
import os
from functools import partial
from typing import Any, Dict, Generic, List, Optional, Tuple, TypeVar, Union, overload

from ..errors import UsageError
from ..files import PathLike
from ..units import parse_unit
from . import settings as _settings
from .config_io import read_settings_file, write_toml
from .surfaces import Region, Surface

__all__ = [
    "QuantifyConfig",
    "SceneConditions",
    "Methods",
    "Execution",
    "Record",
    "FIELDS",
    "VELOCITY_SOURCES",
]


#: The velocity sources (qogi.measure.velocimetry's methods and the given speeds
#: ``wind`` and ``exit``): the settings table's choices.
VELOCITY_SOURCES = _settings.choices("velocity")


def _from_table(name: str) -> Any:
    """A role object's field whose default is the settings table's (a new
    value for each object, so that lists and dicts are not shared)."""
    return dataclasses.field(default_factory=partial(_settings.default, name))


def _check_fields(obj) -> None:
    """Each field of a role object checked, and put in its canonical form,
    by the settings table (qogi.pipeline.settings.check)."""
    for f in dataclasses.fields(obj):
        setattr(obj, f.name, _settings.check(f.name, getattr(obj, f.name)))


@dataclasses.dataclass
class SceneConditions:
    """Facts about the scene and the gas (None: the recording's)."""

    species: List[str] = _from_table("species")
    gas_temperature: Union[str, float] = _from_table("gas_temperature")
    composition: Optional[Dict[str, float]] = _from_table("composition")
    exit_temperature_K: Optional[float] = _from_table("exit_temperature_K")
    distance_m: Optional[float] = _from_table("distance_m")
    ambient_temperature_K: Optional[float] = _from_table("ambient_temperature_K")
    pressure_Pa: Optional[float] = _from_table("pressure_Pa")
    source: Optional[Tuple[float, float]] = _from_table("source")
    sigma_m: Optional[float] = _from_table("sigma_m")
    wind_speed_m_s: Optional[float] = _from_table("wind_speed_m_s")
    exit_velocity_m_s: Optional[float] = _from_table("exit_velocity_m_s")

    def __post_init__(self):
        _check_fields(self)
        if self.composition is not None and self.species is not None:
            missing = [sp for sp in self.species if sp not in self.composition]
            if missing:
                raise _settings.SettingError(
                    "composition",
                    "needs a volume fraction > 0 for every species quantified "
                    f"({self.species}); got {self.composition}",
                )

    @property
    def infers_temperature(self) -> bool:
        """True when the gas temperature is inferred on the mixing line."""
        return self.gas_temperature == "infer"


@dataclasses.dataclass
class Methods:
    """The analysis choices (each changes the result; docs/pipeline_api.md)."""

    velocity: str = _from_table("velocity")
    averaging: str = _from_table("averaging")
    background: Union[str, Region] = _from_table("background")
    background_percentile: float = _from_table("background_percentile")
    column_density: str = _from_table("column_density")
    velocity_systematic: Optional[float] = _from_table("velocity_systematic")
    column_systematic: Optional[float] = _from_table("column_systematic")
    flux_level: bool = _from_table("flux_level")
    line_shape: str = _from_table("line_shape")

    def __post_init__(self):
        _check_fields(self)

    @property
    def given_speed(self) -> bool:
        """True for a user-given speed (``wind``, ``exit``) instead of velocimetry."""
        return self.velocity in ("wind", "exit")

    @property
    def truth_columns(self) -> bool:
        """True for the synthetic truth maps' columns (validation)."""
        return self.column_density == "truth"

    @property
    def time_averaged(self) -> bool:
        return self.averaging == "time-averaged"

    @property
    def region_background(self) -> bool:
        """True for a user-given gas-free region."""
        return isinstance(self.background, Region)


@dataclasses.dataclass
class Execution:
    """How the run is carried out (frames analysed, threads, streaming)."""

    frames: Optional[Tuple[int, int]] = _from_table("frames")
    num_threads: int = _from_table("num_threads")
    pair_stride: Optional[int] = _from_table("pair_stride")
    block_frames: Optional[int] = _from_table("block_frames")

    def __post_init__(self):
        _check_fields(self)


@dataclasses.dataclass
class Record:
    """Who measured what, where (each optional): written into the result's
    audit record (``Result.audit``); they change nothing computed."""

    site: Optional[str] = _from_table("site")
    component: Optional[str] = _from_table("component")
    operator: Optional[str] = _from_table("operator")
    location: Optional[str] = _from_table("location")

    def __post_init__(self):
        _check_fields(self)


_GROUPS = {
    "conditions": SceneConditions,
    "methods": Methods,
    "execution": Execution,
    "record": Record,
}

#: The flat keys of :class:`QuantifyConfig`, in their saved order, with the
#: role (attribute of the config) each belongs to: the settings table's
#: (qogi.pipeline.settings.SETTINGS).
FIELDS: Dict[str, str] = {name: _settings.ROLES[s.role] for name, s in _settings.SETTINGS.items()}

assert set(FIELDS) == {f.name for g in _GROUPS.values() for f in dataclasses.fields(g)}


def _default(name: str):
    f = next(f for f in dataclasses.fields(_GROUPS[FIELDS[name]]) if f.name == name)
    if f.default is not dataclasses.MISSING:
        return f.default
    assert f.default_factory is not dataclasses.MISSING  # every role field has a default
    return f.default_factory()


T = TypeVar("T")


class _Flat(Generic[T]):
    """A flat key of the config, read from and written to its role's object
    (typed: ``cfg.velocity`` is the ``str`` of ``cfg.methods.velocity``)."""

    def __set_name__(self, owner, name: str) -> None:
        self.name, self.group = name, FIELDS[name]

    @overload
    def __get__(self, obj: None, owner: Any = None) -> _Flat[T]: ...

    @overload
    def __get__(self, obj: QuantifyConfig, owner: Any = None) -> T: ...

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        return getattr(obj.__dict__[self.group], self.name)

    def __set__(self, obj: QuantifyConfig, value: T) -> None:
        setattr(obj.__dict__[self.group], self.name, value)


class QuantifyConfig:
    """Settings of :func:`qogi.quantify` (validated on construction; see
    docs/pipeline_api.md for each field).

    Built from the flat keys (``QuantifyConfig(species=["CH4"],
    velocity="wind", wind_speed_m_s=3.0)``) and read flat (``cfg.velocity``);
    held as four role objects: :attr:`conditions` (:class:`SceneConditions`),
    :attr:`methods` (:class:`Methods`), :attr:`execution`
    (:class:`Execution`) and :attr:`record` (:class:`Record`)."""

    conditions: SceneConditions
    methods: Methods
    execution: Execution
    record: Record

    # The flat keys, each read from and written to its role's object.
    species: _Flat[List[str]] = _Flat()
    gas_temperature: _Flat[Union[str, float]] = _Flat()
    velocity: _Flat[str] = _Flat()
    wind_speed_m_s: _Flat[Optional[float]] = _Flat()
    exit_velocity_m_s: _Flat[Optional[float]] = _Flat()
    averaging: _Flat[str] = _Flat()
    background: _Flat[Union[str, Region]] = _Flat()
    background_percentile: _Flat[float] = _Flat()
    source: _Flat[Optional[Tuple[float, float]]] = _Flat()
    distance_m: _Flat[Optional[float]] = _Flat()
    ambient_temperature_K: _Flat[Optional[float]] = _Flat()
    pressure_Pa: _Flat[Optional[float]] = _Flat()
    sigma_m: _Flat[Optional[float]] = _Flat()
    frames: _Flat[Optional[Tuple[int, int]]] = _Flat()
    num_threads: _Flat[int] = _Flat()
    composition: _Flat[Optional[Dict[str, float]]] = _Flat()
    column_density: _Flat[str] = _Flat()
    velocity_systematic: _Flat[Optional[float]] = _Flat()
    column_systematic: _Flat[Optional[float]] = _Flat()
    flux_level: _Flat[bool] = _Flat()
    pair_stride: _Flat[Optional[int]] = _Flat()
    block_frames: _Flat[Optional[int]] = _Flat()
    line_shape: _Flat[str] = _Flat()
    exit_temperature_K: _Flat[Optional[float]] = _Flat()
    site: _Flat[Optional[str]] = _Flat()
    component: _Flat[Optional[str]] = _Flat()
    operator: _Flat[Optional[str]] = _Flat()
    location: _Flat[Optional[str]] = _Flat()

    def __init__(self, **kwargs):
        unknown = sorted(set(kwargs) - set(FIELDS))
        if unknown:
            raise TypeError(
                f"QuantifyConfig() got unexpected keyword argument(s) {', '.join(unknown)}"
            )
        for group, cls in _GROUPS.items():
            self.__dict__[group] = cls(**{k: v for k, v in kwargs.items() if FIELDS[k] == group})
        self._check_across()

    def _check_across(self) -> None:
        """Checks that tie the roles together (a speed not given may still
        come from the recording: :meth:`completed` checks it then)."""
        m, c = self.methods, self.conditions
        if m.velocity == "exit" and c.exit_velocity_m_s is None:
            raise _settings.SettingError(
                "exit_velocity_m_s",
                "must be given for velocity='exit' (the release's exit velocity, "
                f"{_settings.SETTINGS['exit_velocity_m_s'].range_text()})",
            )

    def completed(self, scene) -> Tuple[QuantifyConfig, Dict[str, Any]]:
        """This config with every scene fact not given taken from the
        recording's ``scene`` (:class:`qogi.Scene`), else its fallback
        (qogi.pipeline.settings.complete), and the facts so taken (name -> value).

        Raises
        ------
        qogi.pipeline.settings.SettingError
            A fact the run needs that neither the config nor the recording
            gives (``velocity="wind"`` without a wind speed), or one the
            recording holds outside the accepted range.
        """
        flat, taken = _settings.complete(self.to_dict(), scene)
        if flat["velocity"] == "wind" and flat["wind_speed_m_s"] is None:
            raise _settings.SettingError(
                "wind_speed_m_s",
                "must be given for velocity='wind' (the recording's /scene holds "
                f"no wind speed); accepted: {_settings.describe('wind_speed_m_s')}",
            )
        bg = flat["background"]
        if isinstance(bg, dict):
            flat["background"] = Region(**bg)
        return self.replace(**flat), taken

    @classmethod
    def from_parts(
        cls,
        conditions: Optional[SceneConditions] = None,
        methods: Optional[Methods] = None,
        execution: Optional[Execution] = None,
        record: Optional[Record] = None,
    ) -> QuantifyConfig:
        """The config of four role objects (defaults for those not given)."""
        parts: Dict[str, Union[SceneConditions, Methods, Execution, Record]] = {
            "conditions": conditions or SceneConditions(),
            "methods": methods or Methods(),
            "execution": execution or Execution(),
            "record": record or Record(),
        }
        flat = {}
        for obj in parts.values():
            flat.update({f.name: getattr(obj, f.name) for f in dataclasses.fields(obj)})
        return cls(**flat)

    @staticmethod
    def field_names() -> List[str]:
        """The flat keys, in their saved order."""
        return list(FIELDS)

    @staticmethod
    def default(name: str):
        """The default value of flat key ``name``."""
        return _default(name)

    def replace(self, **changes) -> QuantifyConfig:
        """A copy with the given flat keys changed (validated again)."""
        flat = {name: getattr(self, name) for name in FIELDS}
        flat.update(changes)
        return QuantifyConfig(**flat)

    def to_dict(self) -> dict:
        d = {}
        for name in FIELDS:
            v = getattr(self, name)
            d[name] = dataclasses.asdict(v) if isinstance(v, Region) else _plain(v)
        return d

    def __eq__(self, other) -> bool:
        if not isinstance(other, QuantifyConfig):
            return NotImplemented
        return all(getattr(self, g) == getattr(other, g) for g in _GROUPS)

    __hash__ = None  # type: ignore[assignment]  # unhashable (mutable), as the dataclass was

    def __repr__(self) -> str:
        return "QuantifyConfig(" + ", ".join(f"{n}={getattr(self, n)!r}" for n in FIELDS) + ")"

    def __getstate__(self):
        return {g: getattr(self, g) for g in _GROUPS}

    def __setstate__(self, state):
        self.__dict__.update(state)

    def __copy__(self):
        return self.replace()

    def __deepcopy__(self, memo):
        return self.replace()

    @classmethod
    def from_dict(cls, d: dict) -> QuantifyConfig:
        """The config :meth:`to_dict` wrote (JSON-friendly lists accepted);
        unknown keys raise ``qogi.UsageError`` naming them and the known ones;
        values are checked by the settings table
        (:func:`qogi.pipeline.settings.from_value`) and the config."""
        if not isinstance(d, dict):
            raise UsageError(f"a config must be a table of settings; got {type(d).__name__}")
        fields = cls.field_names()
        unknown = sorted(set(d) - set(fields))
        if unknown:
            raise UsageError(f"unknown setting(s) {', '.join(unknown)}; known: {', '.join(fields)}")
        # Each value read as the settings table reads a file's values (a table or
        # four numbers for a background region, lists for pairs; text as on the
        # command line): the same values are accepted, with the same messages.
        kw = {k: v if v is None else _settings.from_value(k, v) for k, v in d.items()}
        try:
            return cls(**kw)
        except TypeError as e:
            raise UsageError(f"invalid settings: {e}") from e

    @classmethod
    def from_toml(cls, path) -> QuantifyConfig:
        """The config of a settings file (TOML, or a result JSON); see :func:`load_settings`."""
        return load_settings(path).config

    def to_toml(self, path, surfaces=(), units=None) -> None:
        """Write this config (and optionally surfaces and the reporting unit)
        as a settings file that :meth:`from_toml` and ``--config`` read back."""
        write_toml(path, self, surfaces, units)


def _plain(v):
    """A deep copy of a setting's value as dataclasses.asdict made it."""
    if isinstance(v, list):
        return [_plain(x) for x in v]
    if isinstance(v, tuple):
        return tuple(_plain(x) for x in v)
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    return v


assert all(isinstance(QuantifyConfig.__dict__.get(n), _Flat) for n in FIELDS), (
    "a flat key undeclared"
)


# --------------------------------------------------------------------------- settings files

#: Keys of a settings file beside the config's fields.
SETTINGS_KEYS = ("units", "surfaces")


@dataclasses.dataclass
class Settings:
    """What a settings file or result JSON holds: the config, the control
    surfaces (possibly empty) and the reporting unit (None: not given)."""

    config: QuantifyConfig
    surfaces: List[Surface]
    units: Optional[str] = None


def _settings_from_mapping(d: dict, where: str) -> Settings:

    if d.get("format") == "qogi-result":
        cfg = QuantifyConfig.from_dict(d.get("config") or {})
        surfaces = [Surface.from_dict(s) for s in d.get("surfaces", [])]
        units = d.get("units")
        return Settings(cfg, surfaces, parse_unit(units) if units else None)
    rest = {k: v for k, v in d.items() if k not in SETTINGS_KEYS}
    cfg = QuantifyConfig.from_dict(rest)
    surfaces = []
    for k, s in enumerate(d.get("surfaces") or []):
        if not isinstance(s, dict) or "points" not in s:
            raise UsageError(f"{where}: surfaces[{k}] needs points = [[x, y], ...]; got {s!r}")
        surfaces.append(Surface([tuple(p) for p in s["points"]], name=s.get("name") or f"S{k + 1}"))
    units = d.get("units")
    return Settings(cfg, surfaces, parse_unit(units) if units else None)


def load_settings(path: PathLike) -> Settings:
    """Settings from a ``.toml`` file or a ``.json`` (a result or a plain
    config dict; the file format: :mod:`qogi.pipeline.config_io`). Raises
    UsageError for a missing file, bad syntax or a bad value, naming the file."""
    p = os.fspath(path)
    d = read_settings_file(path)
    try:
        return _settings_from_mapping(d, p)
    except ValueError as e:  # UsageError or a config check
        raise UsageError(f"{p}: {e}") from e
