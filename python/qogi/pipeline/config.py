"""The settings of a run, split by role.

:class:`QuantifyConfig` is what callers build, save and load: one flat set of
keys (docs/pipeline_api.md; the keys of settings files, result JSONs, batch
tables, the viewer's form and the command line). Inside it the settings are
three objects, each validating its own fields:

* :class:`SceneConditions`: facts about the scene and the gas that override
  or complete the recording's (the gas, its temperature and composition, the
  distance, ambient temperature and pressure, the source, the plume depth, a
  given wind or exit speed);
* :class:`Methods`: the analysis choices that change the result
  (velocimetry, background, averaging, column source, budget overrides, line
  shape, flux level);
* :class:`Execution`: how the run is carried out (which frames, threads,
  pair stride, streamed block length).

``QuantifyConfig(**flat)``, ``cfg.name`` (read and assignment),
:meth:`QuantifyConfig.to_dict` / :meth:`~QuantifyConfig.from_dict` and the TOML
round trip all use the flat keys, in the order of :data:`FIELDS`.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Dict, Generic, List, Optional, Tuple, TypeVar, Union, overload

import numpy as np

from ..surfaces import Region

__all__ = [
    "QuantifyConfig",
    "SceneConditions",
    "Methods",
    "Execution",
    "FIELDS",
    "VELOCITY_SOURCES",
]

#: The velocimetry sources (qogi.velocimetry's method names, and the given
#: speeds ``wind`` and ``exit``).
VELOCITY_SOURCES = (
    "fluid",
    "horn_schunck",
    "lucas_kanade",
    "farneback",
    "dis",
    "piv",
    "wind",
    "exit",
)
_VELOCITY_SOURCES = VELOCITY_SOURCES


@dataclasses.dataclass
class SceneConditions:
    """Facts about the scene and the gas (None: the recording's)."""

    species: List[str] = dataclasses.field(default_factory=lambda: ["CH4"])
    gas_temperature: Union[str, float] = "ambient"
    composition: Optional[Dict[str, float]] = None
    exit_temperature_K: Optional[float] = None
    distance_m: Optional[float] = None
    ambient_temperature_K: Optional[float] = None
    pressure_Pa: Optional[float] = None
    source: Optional[Tuple[float, float]] = None
    sigma_m: Optional[float] = None
    wind_speed_m_s: Optional[float] = None
    exit_velocity_m_s: Optional[float] = None

    def __post_init__(self):
        if isinstance(self.species, str):
            self.species = [self.species]
        self.species = list(self.species)
        if not self.species:
            raise ValueError("species is empty; e.g. species=['CH4']")
        from .. import _engine

        for sp in self.species:
            _engine.molar_mass(sp)
        g = self.gas_temperature
        if isinstance(g, str):
            if g not in ("ambient", "infer"):
                raise ValueError(
                    f"gas_temperature must be 'ambient', 'infer' or a temperature in K; got {g!r}"
                )
        elif not (np.isfinite(g) and 150.0 <= float(g) <= 600.0):
            raise ValueError(f"gas_temperature must be within [150, 600] K; got {g}")
        for name, lo, hi in (
            ("distance_m", 1e-3, 1e5),
            ("ambient_temperature_K", 180, 350),
            ("pressure_Pa", 3e4, 1.1e5),
            ("sigma_m", 1e-4, 10.0),
        ):
            v = getattr(self, name)
            if v is not None and not (np.isfinite(v) and lo <= v <= hi):
                raise ValueError(f"{name} must be within [{lo:g}, {hi:g}]; got {v}")
        if self.exit_temperature_K is not None and not (
            np.isfinite(self.exit_temperature_K) and 150.0 <= self.exit_temperature_K <= 900.0
        ):
            raise ValueError(
                f"exit_temperature_K must be within [150, 900] K; got {self.exit_temperature_K}"
            )
        if self.source is not None:
            from ..errors import UsageError

            try:
                x, y = (float(v) for v in self.source)
            except (TypeError, ValueError):
                raise UsageError(
                    f"source must be a pixel position (x, y); got {self.source!r}"
                ) from None
            if not (math.isfinite(x) and math.isfinite(y)):
                raise UsageError(f"source must be a finite pixel position (x, y); got ({x}, {y})")
            self.source = (x, y)
        if self.composition is not None:
            comp = {str(k): float(v) for k, v in dict(self.composition).items()}
            missing = [sp for sp in self.species if sp not in comp]
            if missing or any(not (np.isfinite(v) and v > 0) for v in comp.values()):
                raise ValueError(
                    "composition needs a volume fraction > 0 for every species "
                    f"quantified ({self.species}); got {self.composition}"
                )
            self.composition = comp

    @property
    def infers_temperature(self) -> bool:
        """True when the gas temperature is inferred on the mixing line."""
        return self.gas_temperature == "infer"


@dataclasses.dataclass
class Methods:
    """The analysis choices (each changes the result; docs/pipeline_api.md)."""

    velocity: str = "fluid"
    averaging: str = "per-frame"
    background: Union[str, Region] = "auto"
    background_percentile: float = 5.0
    column_density: str = "inversion"
    velocity_systematic: Optional[float] = None
    column_systematic: Optional[float] = None
    flux_level: bool = True
    line_shape: str = "fixed:25+self"

    def __post_init__(self):
        # qogi.velocimetry's method names; the hyphenated spellings are accepted too.
        self.velocity = str(self.velocity).replace("-", "_")
        if self.velocity not in VELOCITY_SOURCES:
            raise ValueError(
                f"velocity must be one of {', '.join(VELOCITY_SOURCES)}; got {self.velocity!r}"
            )
        if self.averaging not in ("per-frame", "time-averaged"):
            raise ValueError(
                f"averaging must be 'per-frame' or 'time-averaged'; got {self.averaging!r}"
            )
        if isinstance(self.background, str):
            if self.background not in ("auto", "beside-surface", "percentile"):
                raise ValueError(
                    "background must be 'auto', 'beside-surface', 'percentile' or a "
                    "qogi.Region; "
                    f"got {self.background!r}"
                )
        elif not isinstance(self.background, Region):
            raise ValueError(
                f"background must be a string or a qogi.Region; got {self.background!r}"
            )
        if not 0 <= self.background_percentile <= 50:
            raise ValueError(
                f"background_percentile must be within [0, 50]; got {self.background_percentile}"
            )
        if self.column_density not in ("inversion", "truth"):
            raise ValueError(
                "column_density must be 'inversion' or 'truth' (validation); got "
                f"{self.column_density!r}"
            )
        if self.velocity_systematic is not None and not 0 <= self.velocity_systematic <= 1:
            raise ValueError(
                f"velocity_systematic must be within [0, 1]; got {self.velocity_systematic}"
            )
        if self.column_systematic is not None and not 0 <= self.column_systematic <= 1:
            raise ValueError(
                f"column_systematic must be within [0, 1]; got {self.column_systematic}"
            )
        from ..forward import LineShape

        self.line_shape = str(LineShape.parse(self.line_shape))

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

    frames: Optional[Tuple[int, int]] = None
    num_threads: int = 0
    pair_stride: Optional[int] = None
    block_frames: Optional[int] = None

    def __post_init__(self):
        if self.frames is not None:
            if (
                not isinstance(self.frames, (tuple, list))
                or len(self.frames) != 2
                or not all(_is_integer(v) for v in self.frames)
                or not 0 <= self.frames[0] < self.frames[1]
            ):
                raise ValueError(
                    f"frames must be (start, stop), integers with 0 <= start < stop; "
                    f"got {self.frames!r}"
                )
            self.frames = (int(self.frames[0]), int(self.frames[1]))
        if not _is_integer(self.num_threads) or self.num_threads < 0:
            raise ValueError(
                f"num_threads must be an integer >= 0 (worker threads; 0 = all cores); "
                f"got {self.num_threads!r}"
            )
        self.num_threads = int(self.num_threads)
        if self.pair_stride is not None and (
            not _is_integer(self.pair_stride) or not 1 <= self.pair_stride <= 100
        ):
            raise ValueError(
                f"pair_stride must be an integer within [1, 100] (frames between "
                f"the velocimetry's pairs) or None (automatic); got "
                f"{self.pair_stride!r}"
            )
        if self.block_frames is not None and (
            not _is_integer(self.block_frames) or self.block_frames < 8
        ):
            raise ValueError(
                f"block_frames must be an integer >= 8 (frames streamed per block) "
                f"or None (automatic); got {self.block_frames!r}"
            )
        for name in ("pair_stride", "block_frames"):
            if getattr(self, name) is not None:
                setattr(self, name, int(getattr(self, name)))


def _is_integer(v) -> bool:
    """An int or numpy integer, not a bool (a float, even 2.0, is refused:
    the engine's integer settings must not be rounded silently)."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, bool)


_GROUPS = {"conditions": SceneConditions, "methods": Methods, "execution": Execution}

#: The flat keys of :class:`QuantifyConfig`, in their saved order, with the
#: role (attribute of the config) each belongs to.
FIELDS: Dict[str, str] = {
    "species": "conditions",
    "gas_temperature": "conditions",
    "velocity": "methods",
    "wind_speed_m_s": "conditions",
    "exit_velocity_m_s": "conditions",
    "averaging": "methods",
    "background": "methods",
    "background_percentile": "methods",
    "source": "conditions",
    "distance_m": "conditions",
    "ambient_temperature_K": "conditions",
    "pressure_Pa": "conditions",
    "sigma_m": "conditions",
    "frames": "execution",
    "num_threads": "execution",
    "composition": "conditions",
    "column_density": "methods",
    "velocity_systematic": "methods",
    "column_systematic": "methods",
    "flux_level": "methods",
    "pair_stride": "execution",
    "block_frames": "execution",
    "line_shape": "methods",
    "exit_temperature_K": "conditions",
}

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
    held as three role objects: :attr:`conditions` (:class:`SceneConditions`),
    :attr:`methods` (:class:`Methods`) and :attr:`execution`
    (:class:`Execution`)."""

    conditions: SceneConditions
    methods: Methods
    execution: Execution

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
        """Checks that tie the roles together."""
        m, c = self.methods, self.conditions
        if m.velocity == "wind" and not (
            c.wind_speed_m_s is not None and 0 < c.wind_speed_m_s <= 100
        ):
            raise ValueError(
                f"velocity='wind' needs wind_speed_m_s within (0, 100] m/s; got {c.wind_speed_m_s}"
            )
        if m.velocity == "exit" and not (
            c.exit_velocity_m_s is not None and 0 < c.exit_velocity_m_s <= 500
        ):
            raise ValueError(
                "velocity='exit' needs exit_velocity_m_s within (0, 500] m/s; got "
                f"{c.exit_velocity_m_s}"
            )

    @classmethod
    def from_parts(
        cls,
        conditions: Optional[SceneConditions] = None,
        methods: Optional[Methods] = None,
        execution: Optional[Execution] = None,
    ) -> QuantifyConfig:
        """The config of three role objects (defaults for those not given)."""
        parts: Dict[str, Union[SceneConditions, Methods, Execution]] = {
            "conditions": conditions or SceneConditions(),
            "methods": methods or Methods(),
            "execution": execution or Execution(),
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
        unknown keys raise ``qogi.UsageError`` (qogi.config_io)."""
        from ..config_io import config_from_dict

        return config_from_dict(d)

    @classmethod
    def from_toml(cls, path) -> QuantifyConfig:
        """The config of a settings file (TOML, or a result JSON); see qogi.config_io."""
        from ..config_io import load_settings

        return load_settings(path).config

    def to_toml(self, path, surfaces=(), units=None) -> None:
        """Write this config (and optionally surfaces and the reporting unit)
        as a settings file that :meth:`from_toml` and ``--config`` read back."""
        from ..config_io import write_toml

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
