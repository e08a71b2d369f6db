"""The run's settings, declared once.

Every field of :class:`qogi.QuantifyConfig` is one :class:`Setting` in
:data:`SETTINGS`: its role, kind, unit, accepted range or choices, default,
command-line flag and help text. The key is the same everywhere: the config's
keyword, the settings TOML's key, the result JSON's ``config`` key and the
batch manifest's column. From this table come

* the config's checks (:func:`check`, called by the config's role objects),
* the values of the command line, the manifests' CSV cells and the viewer's
  text fields (:func:`from_text`) and of TOML / JSON files (:func:`from_value`),
* the ``qogi quantify`` options (:func:`add_arguments`),
* the settings table of docs/pipeline_api.md (:func:`markdown_table`),

so that every way in accepts the same values and refuses the same ones with
the same message: a :class:`SettingError` whose :attr:`~SettingError.body`
("must be within [150, 600] K; got 700") each caller puts after its own
locator (``gas_temperature``, ``--gas-temperature``, ``column 'gas_temperature'``).

Roles: ``scene`` (facts about the scene and the gas; None or the documented
default means the recording's value where the recording holds one,
``Setting.scene_key``), ``method`` (analysis choices that change the result),
``execution`` (how the run is carried out) and ``record`` (who measured
what, where: written into the result's audit record, ``Result.audit``;
they change nothing computed).
"""

from __future__ import annotations

import dataclasses
import math
import numbers
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple

from .. import _engine
from ..errors import UsageError
from ..measure import velocimetry
from ..physics.forward import LineShape
from .surfaces import Region

__all__ = [
    "Setting",
    "SettingError",
    "SETTINGS",
    "ROLES",
    "check",
    "from_text",
    "from_value",
    "describe",
    "choices",
    "default",
    "add_arguments",
    "config_overrides",
    "complete",
    "markdown_table",
]

#: Role -> the attribute of QuantifyConfig holding that role's fields.
ROLES = {
    "scene": "conditions",
    "method": "methods",
    "execution": "execution",
    "record": "record",
}


class SettingError(UsageError):
    """A refused setting (a :class:`qogi.UsageError`, hence a ValueError):
    ``name`` (the flat key), ``body`` (what is wrong, the accepted values and
    the value given); ``str()`` is ``"<name> <body>"``."""

    def __init__(self, name: str, body: str):
        self.name, self.body = name, body
        super().__init__(f"{name} {body}")


@dataclasses.dataclass(frozen=True)
class Setting:
    """One field of the run's settings.

    Attributes
    ----------
    name : str
        The flat key (config keyword, TOML key, manifest column, JSON key).
    role : {"scene", "method", "execution", "record"}
    kind : str
        ``float``, ``int``, ``bool``, ``choice``, ``species``,
        ``gas_temperature`` (a choice or a float), ``background`` (a choice
        or a region), ``pair`` (a pixel position), ``frames`` (start, stop),
        ``composition`` (species -> fraction), ``line_shape`` or ``text``
        (one line of free text, at most :data:`TEXT_MAX` characters).
    help : str
        What it means (docs table, ``--help``, the viewer's hints).
    unit : str
        Unit of a number ("" for none).
    lo, hi : float or None
        Accepted closed range of a number (``lo_open``: ``lo`` excluded).
    optional : bool
        None is accepted (meaning given in ``help``).
    flag : str or None
        The ``qogi quantify`` option.
    metavar : str
        The name --help shows for the option's value (argparse's metavar).
    scene_key : str or None
        The recording's ``/scene`` attribute this completes (role scene).
    doc : str
        More than ``help`` for the docs table ("" : ``help`` says it all).
    fallback : object
        The value of a scene fact neither given nor held by the recording
        (None: none needed).
    none : str
        What None means, where messages should say it (``automatic``).
    """

    name: str
    role: str
    kind: str
    help: str
    unit: str = ""
    lo: Optional[float] = None
    hi: Optional[float] = None
    lo_open: bool = False
    optional: bool = False
    flag: Optional[str] = None
    metavar: str = ""
    scene_key: Optional[str] = None
    doc: str = ""
    fallback: Any = None
    none: str = ""
    _choices: Tuple[str, ...] = ()
    _default: Any = None

    @property
    def choices(self) -> Tuple[str, ...]:
        """The accepted words (choice kinds; for velocity, qogi.measure.velocimetry's methods)."""
        return choices(self.name)

    @property
    def default(self) -> Any:
        return default(self.name)

    def range_text(self) -> str:
        """``[150, 600] K``, ``(0, 100] m/s``, ``>= 0``: the accepted numbers."""
        u = f" {self.unit}" if self.unit else ""
        if self.lo is not None and self.hi is not None:
            return f"{'(' if self.lo_open else '['}{self.lo:g}, {self.hi:g}]{u}"
        if self.lo is not None:
            return f"{'>' if self.lo_open else '>='} {self.lo:g}{u}"
        return ""


def _velocity_choices() -> Tuple[str, ...]:

    return tuple(velocimetry.METHODS) + ("wind", "exit")


#: The longest text a ``text`` setting accepts (characters).
TEXT_MAX = 200


#: The settings, in their saved order.
SETTINGS: Dict[str, Setting] = {
    s.name: s
    for s in (
        Setting(
            "species",
            "scene",
            "species",
            "species to quantify (HITRAN names); None: the recording's species, else CH4",
            optional=True,
            flag="--species",
            metavar="NAME[,NAME...]",
            scene_key="species",
            fallback=("CH4",),
        ),
        Setting(
            "gas_temperature",
            "scene",
            "gas_temperature",
            "gas temperature at the plume centre: 'ambient' (assumed equal to the "
            "ambient air), a temperature in K, or 'infer' (needs >= 2 channels: the "
            "multichannel inversion's mixing line). Not completed by the "
            "recording's /scene gas_temperature_K: that is the gas at its "
            "source (a synthetic release writes its exit temperature), far hotter "
            "than the diluted plume at the surfaces",
            unit="K",
            lo=150.0,
            hi=600.0,
            flag="--gas-temperature",
            metavar="ambient|infer|K",
            _choices=("ambient", "infer"),
            _default="ambient",
        ),
        Setting(
            "velocity",
            "method",
            "choice",
            "velocity source: a method of qogi.measure.velocimetry (hyphens accepted), or "
            "'wind' (wind_speed_m_s along each surface's normal), or 'exit' "
            "(exit_velocity_m_s; lab checks)",
            flag="--velocity",
            metavar="METHOD",
        ),
        Setting(
            "wind_speed_m_s",
            "scene",
            "float",
            "the wind speed used with velocity 'wind', along each surface's normal",
            unit="m/s",
            lo=0.0,
            hi=100.0,
            lo_open=True,
            optional=True,
            flag="--wind-speed",
            metavar="M_S",
            scene_key="wind_speed_m_s",
        ),
        Setting(
            "exit_velocity_m_s",
            "scene",
            "float",
            "the release's exit velocity used with velocity 'exit' (lab checks)",
            unit="m/s",
            lo=0.0,
            hi=500.0,
            lo_open=True,
            optional=True,
            flag="--exit-velocity",
            metavar="M_S",
        ),
        Setting(
            "averaging",
            "method",
            "choice",
            "invert every frame then average the rates, or invert the time-averaged frames",
            flag="--averaging",
            _choices=("per-frame", "time-averaged"),
            _default="per-frame",
        ),
        Setting(
            "background",
            "method",
            "background",
            "how the gas-free background radiance is estimated: 'auto' (beside the "
            "surfaces where the strips there are gas-free, else the temporal "
            "percentile; a drifting background where it moves on its own), "
            "'beside-surface', 'percentile', 'drifting', or a gas-free region "
            "x0,y0,x1,y1 (qogi.Region)",
            flag="--background",
            metavar="METHOD|X0,Y0,X1,Y1",
            _choices=("auto", "beside-surface", "percentile", "drifting"),
            _default="auto",
            doc=(
                "`auto`: chosen from the scene (qogi.pipeline.background_choice.choose; below); "
                "`beside-surface`:"
                " the thesis's choice, gas-free pixels just beyond each end of the surface, "
                "interpolated along it; `percentile`: a sign-aware temporal low percentile per "
                "pixel; `drifting`: a static layer and a layer drifting at a velocity "
                "measured apart from the gas (clouds crossing a sky), each a sign-aware "
                "percentile, the drifting one over a running 10 s window; or a `qogi.Region`"
            ),
        ),
        Setting(
            "background_percentile",
            "method",
            "float",
            "temporal low percentile of background 'percentile' (and 'drifting')",
            unit="%",
            lo=0.0,
            hi=50.0,
            flag="--background-percentile",
            metavar="P",
            _default=5.0,
        ),
        Setting(
            "source",
            "scene",
            "pair",
            "source pixel: orients every surface away from it and places the "
            "transport flux level; None: the surfaces keep their left-hand normals",
            unit="px",
            optional=True,
            flag="--source",
            metavar="X,Y",
            doc=(
                "orients all surfaces away from it and places the transport flux level; None: the"
                " surfaces keep their left-hand normals and, for the default fluid velocimetry, "
                "the source of the flux level is detected (`qogi.detect_source` on "
                '`qogi.plume_image` of up to 50 frames; `info["source"]` says where)'
            ),
        ),
        Setting(
            "distance_m",
            "scene",
            "float",
            "camera-to-plume distance; None: the recording's",
            unit="m",
            lo=1e-3,
            hi=1e5,
            optional=True,
            flag="--distance",
            metavar="M",
            scene_key="distance_m",
        ),
        Setting(
            "ambient_temperature_K",
            "scene",
            "float",
            "ambient air temperature; None: the recording's",
            unit="K",
            lo=180.0,
            hi=350.0,
            optional=True,
            flag="--ambient-temperature",
            metavar="K",
            scene_key="ambient_temperature_K",
        ),
        Setting(
            "pressure_Pa",
            "scene",
            "float",
            "ambient pressure; None: the recording's",
            unit="Pa",
            lo=3e4,
            hi=1.1e5,
            optional=True,
            flag="--pressure",
            metavar="PA",
            scene_key="pressure_Pa",
        ),
        Setting(
            "sigma_m",
            "scene",
            "float",
            "plume depth sigma; None: from the plume width across each surface",
            unit="m",
            lo=1e-4,
            hi=10.0,
            optional=True,
            flag="--sigma",
            metavar="M",
            doc="plume depth; None = from the plume width across each surface (axisymmetric)",
        ),
        Setting(
            "frames",
            "execution",
            "frames",
            "frames analysed: START (inclusive) to STOP (exclusive), from 0; None: all",
            optional=True,
            flag="--frames",
            metavar="START:STOP",
        ),
        Setting(
            "num_threads",
            "execution",
            "int",
            "worker threads (0 = all cores)",
            lo=0,
            flag="--threads",
            metavar="N",
            _default=0,
        ),
        Setting(
            "composition",
            "scene",
            "composition",
            "known volume ratio of the released species (e.g. CH4=0.5,CO2=0.5): "
            "ties their fractions, so the bands' contrast ratios measure the temperature",
            optional=True,
            flag="--composition",
            metavar="SP=X[,SP=X...]",
        ),
        Setting(
            "column_density",
            "method",
            "choice",
            "'inversion', or 'truth': a synthetic recording's truth maps (validation "
            "of the rest of the chain)",
            flag="--column-density",
            _choices=("inversion", "truth"),
            _default="inversion",
        ),
        Setting(
            "velocity_systematic",
            "method",
            "float",
            "relative 1-sigma systematic of the velocity in the budget; None: the "
            "method's entry of qogi.pipeline.VELOCITY_SYSTEMATIC",
            flag="--velocity-systematic",
            metavar="FRACTION",
            lo=0.0,
            hi=1.0,
            optional=True,
            doc=(
                "relative 1-sigma systematic of the velocity in the budget (None: the method's "
                "entry of `qogi.pipeline.VELOCITY_SYSTEMATIC`, fluid 0.10)"
            ),
        ),
        Setting(
            "column_systematic",
            "method",
            "float",
            "relative 1-sigma systematic of the columns; None: 0.05 with the gas "
            "temperature given or ambient, 0.13 with it inferred",
            flag="--column-systematic",
            metavar="FRACTION",
            lo=0.0,
            hi=1.0,
            optional=True,
            doc=(
                "relative 1-sigma systematic of the columns (Gaussian line-of-sight profile); "
                "None: 0.05 with the gas temperature given or ambient, 0.13 with it inferred (the"
                " RMS deviation of inverted columns from exact truth maps on the heated synthetic"
                " plumes, 0.83-0.90 of the truth; docs/validation.md)"
            ),
        ),
        Setting(
            "flux_level",
            "method",
            "bool",
            "fluid velocimetry with a source: take the flux level from the transport "
            "of the line-integrated column",
            flag="--flux-level",
            metavar="true|false",
            _default=True,
        ),
        Setting(
            "pair_stride",
            "execution",
            "int",
            "frames between the velocimetry's pairs; None: automatic (about 3 px "
            "of the plume's motion per pair)",
            lo=1,
            hi=100,
            optional=True,
            none="automatic",
            flag="--pair-stride",
            metavar="N",
            doc=(
                "frames between the velocimetry's pairs; None: with the flux level on, ~3 px of "
                "the plume's motion per pair (`qogi.measure.velocimetry.typical_displacement`), "
                "at most "
                "every 4th frame (1 at 15 Hz, 2-4 for the 100 Hz lab releases), else 1; "
                '`info["pair_stride"]` records it'
            ),
        ),
        Setting(
            "block_frames",
            "execution",
            "int",
            "frames streamed per block (the memory bound); None: automatic",
            lo=8,
            optional=True,
            none="automatic",
            flag="--block-frames",
            metavar="N",
            doc=(
                "frames streamed per block (the memory bound, below); None: as many as fit 256"
                " MiB of the block's float32 fields (8 per frame), and at least 10 s of record or"
                " 450 frames, whichever is fewer (150 at 15 Hz, 450 at 100 Hz)"
            ),
        ),
        Setting(
            "line_shape",
            "method",
            "line_shape",
            "line shape of the cross-sections (qogi.physics.forward.LineShape): the wing "
            "rule fixed[:CM1] or hapi (50 half-widths), then +self or +air "
            "broadening (docs/forward_model.md)",
            flag="--line-shape",
            metavar="RULE",
        ),
        Setting(
            "exit_temperature_K",
            "scene",
            "float",
            "the gas's temperature at the exit, when known: checked against an "
            "assumed gas temperature (warning gas-temperature-suspect)",
            unit="K",
            lo=150.0,
            hi=900.0,
            optional=True,
            flag="--exit-temperature",
            metavar="K",
        ),
        Setting(
            "site",
            "record",
            "text",
            "the facility or site surveyed (written into the result's audit record)",
            optional=True,
            flag="--site",
            metavar="TEXT",
        ),
        Setting(
            "component",
            "record",
            "text",
            "the component or equipment leaking (a tag, e.g. valve V-102)",
            optional=True,
            flag="--component",
            metavar="TEXT",
        ),
        Setting(
            "operator",
            "record",
            "text",
            "who recorded or analysed the release (written into the result's audit record)",
            optional=True,
            flag="--operator",
            metavar="TEXT",
        ),
        Setting(
            "location",
            "record",
            "text",
            "where the camera stood (coordinates or a description)",
            optional=True,
            flag="--location",
            metavar="TEXT",
        ),
    )
}


def _setting(name: str) -> Setting:
    try:
        return SETTINGS[name]
    except KeyError:
        raise KeyError(f"no setting {name!r}; known: {', '.join(SETTINGS)}") from None


def choices(name: str) -> Tuple[str, ...]:
    """The words setting ``name`` accepts (empty for a number)."""
    if name == "velocity":
        return _velocity_choices()
    return _setting(name)._choices


def default(name: str) -> Any:
    """The default of setting ``name`` (a fresh copy for a list). Defaults
    owned elsewhere are read from their owner: the velocimetry method from
    ``qogi.measure.velocimetry.DEFAULT_METHOD``, the line shape from
    ``qogi.physics.forward.LineShape()``."""
    if name == "velocity":
        return velocimetry.DEFAULT_METHOD
    if name == "line_shape":
        return str(LineShape())
    d = _setting(name)._default
    return list(d) if isinstance(d, tuple) else d


# -- checks --------------------------------------------------------------------


def _is_number(v) -> bool:
    return isinstance(v, numbers.Real) and not isinstance(v, bool)


def _is_integer(v) -> bool:
    return isinstance(v, numbers.Integral) and not isinstance(v, bool)


def _fmt(v) -> str:
    """A value as messages quote it: text in quotes, a float in its
    shortest form that reads back the same (700, 0.5, 1e+06)."""
    if isinstance(v, str):
        return repr(v)
    if isinstance(v, float):
        short = format(v, "g")
        return short if not math.isfinite(v) or float(short) == v else repr(v)
    return f"{v}"


def _check_number(s: Setting, v, integer: bool = False):
    alt = f" or None ({s.none})" if s.none else ""
    if integer:
        if not _is_integer(v):
            # A float is quoted as written (2.0, not 2): an integer setting
            # refuses it rather than rounding it silently.
            got = repr(v) if isinstance(v, float) else _fmt(v)
            raise SettingError(s.name, f"must be a whole number{alt}; got {got}")
        v = int(v)
    else:
        if not _is_number(v):
            raise SettingError(s.name, f"must be a number; got {_fmt(v)}")
        v = float(v)
        if not math.isfinite(v):
            raise SettingError(s.name, f"must be a finite number; got {_fmt(v)}")
    low_ok = s.lo is None or (v > s.lo if s.lo_open else v >= s.lo)
    high_ok = s.hi is None or v <= s.hi
    if not (low_ok and high_ok):
        what = "within " if s.hi is not None else ""
        note = " (0 = all cores)" if s.name == "num_threads" else ""
        raise SettingError(s.name, f"must be {what}{s.range_text()}{note}{alt}; got {_fmt(v)}")
    return v


def _check_choice(s: Setting, v, words: Sequence[str], other: str = ""):
    if not isinstance(v, str) or v not in words:
        listed = ", ".join(words)
        raise SettingError(s.name, f"must be one of {listed}{other}; got {_fmt(v)}")
    return v


def check(name: str, value):
    """The value of setting ``name`` in its canonical form (a float, an int,
    a tuple, a list of names, ...), or :class:`SettingError`.

    Parameters
    ----------
    name : str
        A key of :data:`SETTINGS`.
    value
        A Python value (what :func:`from_text` or :func:`from_value` made).
    """
    s = _setting(name)
    if value is None:
        if s.optional:
            return None
        raise SettingError(name, f"must be given (default {default(name)!r}); got None")
    kind = s.kind
    if kind == "float":
        return _check_number(s, value)
    if kind == "int":
        return _check_number(s, value, integer=True)
    if kind == "bool":
        if not isinstance(value, (bool,)) and type(value).__name__ != "bool_":
            raise SettingError(name, f"must be true or false; got {_fmt(value)}")
        return bool(value)
    if kind == "choice":
        if name == "velocity" and isinstance(value, str):
            value = value.replace("-", "_")  # qogi.measure.velocimetry's names, hyphens accepted
        return _check_choice(s, value, choices(name))
    if kind == "species":
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, (list, tuple)) or not all(isinstance(x, str) for x in value):
            raise SettingError(name, f"must be a list of species names; got {_fmt(value)}")
        value = [x.strip() for x in value]
        if not value or not all(value):
            raise SettingError(name, f"must name at least one species (e.g. CH4); got {value}")

        for sp in value:
            try:
                _engine.molar_mass(sp)  # the engine knows the species it can model
            except ValueError as e:
                raise SettingError(name, f"{e}") from None
        return value
    if kind == "gas_temperature":
        if isinstance(value, str):
            return _check_choice(s, value, s._choices, " or a temperature in K")
        return _check_number(s, value)
    if kind == "background":
        if isinstance(value, Region):
            return value
        return _check_choice(s, value, s._choices, " or a region x0,y0,x1,y1")
    if kind == "pair":
        ok = isinstance(value, (list, tuple)) and len(value) == 2 and all(map(_is_number, value))
        if not ok:
            raise SettingError(name, f"must be a pixel position (x, y); got {_fmt(value)}")
        x, y = (float(v) for v in value)
        if not (math.isfinite(x) and math.isfinite(y)):
            raise SettingError(
                name, f"must be a finite pixel position (x, y); got ({_fmt(x)}, {_fmt(y)})"
            )
        return (x, y)
    if kind == "frames":
        ok = isinstance(value, (list, tuple)) and len(value) == 2
        if not ok or not all(map(_is_integer, value)) or not 0 <= value[0] < value[1]:
            raise SettingError(
                name,
                f"must be (start, stop), whole numbers with 0 <= start < stop; got {_fmt(value)}",
            )
        return (int(value[0]), int(value[1]))
    if kind == "composition":
        if not isinstance(value, dict):
            raise SettingError(
                name, f"must map species to volume fractions, e.g. CH4=0.5,CO2=0.5; got {value!r}"
            )
        out = {}
        for k, x in value.items():
            if not (_is_number(x) and math.isfinite(x) and x > 0):
                raise SettingError(name, f"needs a volume fraction > 0 per species; got {value}")
            out[str(k)] = float(x)
        return out
    if kind == "text":
        if not isinstance(value, str):
            raise SettingError(name, f"must be text; got {_fmt(value)}")
        t = value.strip()
        if not t:
            raise SettingError(name, "is empty: type the text, or leave the setting out")
        if len(t) > TEXT_MAX:
            raise SettingError(name, f"must be at most {TEXT_MAX} characters; got {len(t)}")
        if any(not c.isprintable() for c in t):
            raise SettingError(
                name, f"must be one line of printable text (no tabs or line breaks); got {t!r}"
            )
        return t
    if kind == "line_shape":
        try:
            return str(LineShape.parse(value))
        except (ValueError, TypeError) as e:
            raise SettingError(name, f"{value!r}: {_line_shape_problem(e)}") from None
    raise AssertionError(f"setting {name}: unknown kind {kind}")  # pragma: no cover


def _line_shape_problem(e: Exception) -> str:
    """LineShape's message without its own 'line shape <text>:' prefix."""
    text = str(e)
    if text.startswith("line shape "):
        text = text[len("line shape ") :]
        if ": " in text and text.startswith("'"):
            text = text.split(": ", 1)[1]
    return text


# -- scene facts: the recording completes what was not given ------------------


def complete(values: Dict[str, Any], scene) -> Tuple[Dict[str, Any], Dict[str, Any]]:
    """The settings ``values`` (flat keys) with each scene fact not given
    taken from the recording's ``scene`` (a :class:`qogi.Scene`), else its
    fallback; and the facts taken from the recording (name -> value).

    A given value always wins. The recording's wind speed is taken only for
    ``velocity="wind"`` (the only use of it). A value the recording holds
    that the setting does not accept is a :class:`SettingError` saying so.
    """
    out = dict(values)
    taken: Dict[str, Any] = {}
    for s in SETTINGS.values():
        if not s.scene_key or out.get(s.name) is not None:
            continue
        if s.name == "wind_speed_m_s" and out.get("velocity") != "wind":
            continue
        held = getattr(scene, s.scene_key, None)
        if held is not None and not (isinstance(held, (tuple, list)) and not held):
            held = list(held) if isinstance(held, (tuple, list)) else held
            try:
                out[s.name] = check(s.name, held)
            except SettingError as e:
                raise SettingError(
                    s.name,
                    f"was not given, and the recording's /scene {s.scene_key} "
                    f"{e.body}: give {s.name}",
                ) from None
            taken[s.name] = out[s.name]
        elif s.fallback is not None:
            f = s.fallback
            out[s.name] = list(f) if isinstance(f, tuple) else f
    return out, taken


# -- from text (command line, CSV cell, the viewer's fields) -------------------


def _text_number(s: Setting, text: str, integer: bool = False):
    t = text.strip()
    if not t:
        raise SettingError(s.name, "is empty: type a number")
    try:
        return int(t) if integer else float(t)
    except ValueError:
        pass
    try:
        return float(t)  # a number, but not a whole one: check() says so
    except ValueError:
        what = "a whole number" if integer else "a number"
        raise SettingError(s.name, f"must be {what}; got {t!r}") from None


def _text_numbers(s: Setting, text: str, sep: str) -> List[str]:
    return [p.strip() for p in text.replace(";", sep).split(sep)]


def _two(name: str, t: str, sep: str, convert, form: str, what: str) -> tuple:
    """Two values written ``A<sep>B`` (``X,Y``, ``START:STOP``)."""
    parts = t.split(sep)
    if len(parts) != 2:
        raise SettingError(name, f"expected {form} (two {what} separated by {sep!r}); got {t!r}")
    try:
        return tuple(convert(p) for p in parts)
    except ValueError:
        raise SettingError(name, f"expected {form} as {what}; got {t!r}") from None


def from_text(name: str, text: str):
    """The checked value of setting ``name`` written as text: a command-line
    argument, a CSV manifest's cell, a viewer's field (:func:`check`'s
    messages, plus what is wrong with the text's form).

    Forms: numbers; ``ambient``/``infer`` or K; a choice word; ``x,y``;
    ``START:STOP``; ``CH4,CO2``; ``CH4=0.5,CO2=0.5``; ``x0,y0,x1,y1`` (a
    background region); ``true``/``false``; a line-shape rule.
    """
    s = _setting(name)
    t = str(text).strip()
    kind = s.kind
    if kind == "float":
        return check(name, _text_number(s, t))
    if kind == "int":
        return check(name, _text_number(s, t, integer=True))
    if kind == "bool":
        low = t.lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise SettingError(name, f"must be true or false; got {t!r}")
    if kind in ("choice", "line_shape", "text"):
        return check(name, t)
    if kind == "species":
        return check(name, [p for p in _text_numbers(s, t, ",") if p] or [""])
    if kind == "gas_temperature":
        if t.lower() in s._choices:
            return t.lower()
        try:
            v = float(t)
        except ValueError:
            raise SettingError(
                name, f"must be one of {', '.join(s._choices)} or a temperature in K; got {t!r}"
            ) from None
        return check(name, v)
    if kind == "background":
        if t in s._choices or "," not in t:
            return check(name, t)

        parts = _text_numbers(s, t, ",")
        try:
            xs = [float(p) for p in parts]
        except ValueError:
            xs = []
        if len(xs) != 4 or not all(math.isfinite(x) and x == int(x) for x in xs):
            raise SettingError(
                name, f"a region is x0,y0,x1,y1, four whole pixel numbers; got {t!r}"
            )
        return Region(*[int(x) for x in xs])
    if kind == "pair":
        return check(name, _two(name, t, ",", float, "X,Y", "numbers"))
    if kind == "frames":
        return check(name, _two(name, t, ":", int, "START:STOP", "whole numbers"))
    if kind == "composition":
        out: Dict[str, Any] = {}
        for part in _text_numbers(s, t, ","):
            if not part:
                continue
            k, eq, x = part.partition("=")
            try:
                out[k.strip()] = float(x) if eq else None
            except ValueError:
                out[k.strip()] = None
            if out[k.strip()] is None:
                raise SettingError(
                    name, f"expected SPECIES=FRACTION pairs, e.g. CH4=0.5,CO2=0.5; got {t!r}"
                )
        return check(name, out)
    raise AssertionError(f"setting {name}: unknown kind {kind}")  # pragma: no cover


def from_value(name: str, value):
    """The checked value of setting ``name`` as a TOML / JSON file or Python
    holds it: lists for pairs, a table ``{x0, y0, x1, y1}`` (or four numbers)
    for a background region; text is read as :func:`from_text` reads it (a
    manifest's ``source = "159.5,227"`` is its CSV cell)."""
    s = _setting(name)
    if isinstance(value, str):
        return from_text(name, value)
    if s.kind == "background" and isinstance(value, (dict, list, tuple)):
        try:
            if isinstance(value, dict):
                xs = [value[k] for k in ("x0", "y0", "x1", "y1")]
            else:
                xs = list(value)
            if len(xs) != 4 or not all(map(_is_integer, xs)):
                raise ValueError
        except (KeyError, ValueError):
            raise SettingError(
                name, f"a region is x0,y0,x1,y1, four whole pixel numbers; got {value!r}"
            ) from None
        return Region(*xs)
    return check(name, value)


# -- what a setting accepts, in words (--help, the viewer's hints, the docs) ---


def describe(name: str) -> str:
    """What setting ``name`` accepts: its choices and/or range and unit."""
    s = _setting(name)
    words = choices(name)
    parts = []
    if s.kind == "background":
        parts.append(", ".join(words) + " or a region x0,y0,x1,y1")
    elif words:
        parts.append(", ".join(words))
    if s.kind in ("float", "int", "gas_temperature"):
        parts.append(s.range_text() or (f"a number [{s.unit}]" if s.unit else "a number"))
    if s.kind == "bool":
        parts.append("true or false")
    text = " or ".join(p for p in parts if p)
    return text


def _doc_type(s: Setting) -> str:
    kinds = {
        "float": "float",
        "int": "int",
        "bool": "bool",
        "choice": "str",
        "species": "list of str",
        "gas_temperature": "str or float",
        "background": "str or qogi.Region",
        "pair": "(x, y)",
        "frames": "(start, stop)",
        "composition": "dict",
        "line_shape": "str",
        "text": "str",
    }
    t = kinds[s.kind]
    return t + (" or None" if s.optional else "")


def markdown_table() -> str:
    """The settings table of docs/pipeline_api.md, generated from
    :data:`SETTINGS` (``scripts/settings_table.py`` writes it there; a test
    checks the committed table is this one)."""
    rows = [
        "| field | role | type | accepts | default | CLI | meaning |",
        "|---|---|---|---|---|---|---|",
    ]
    for s in SETTINGS.values():
        d = default(s.name)
        dtext = "None" if d is None else "`" + repr(d).replace("'", '"') + "`"
        if s.fallback is not None:
            f = list(s.fallback) if isinstance(s.fallback, tuple) else s.fallback
            dtext += " (the recording's, else `" + repr(f).replace("'", '"') + "`)"
        if s.kind == "line_shape":
            acc = "`fixed[:CM1]` (CM1 in [1, 100]) or `hapi`, then `+self` or `+air`"
        elif s.kind == "text":
            acc = f"one line of text, at most {TEXT_MAX} characters"
        elif s.kind in ("pair", "frames", "species", "composition"):
            acc = f"`{s.metavar}`"
        else:
            acc = describe(s.name)
        cli = f"`{s.flag}`" if s.flag else ""
        meaning = s.doc or s.help
        if s.scene_key:
            meaning += f" (recording: `/scene` `{s.scene_key}`)"
        cells = [f"`{s.name}`", s.role, _doc_type(s), acc, dtext, cli, meaning]
        rows.append("| " + " | ".join(c.replace("|", "\\|") for c in cells) + " |")
    return "\n".join(rows) + "\n"


# -- the command line ----------------------------------------------------------


def arg_type(name: str) -> Callable[[str], Any]:
    """An argparse ``type`` for setting ``name``: :func:`from_text`, its
    message turned into argparse's usage error (exit 2)."""
    import argparse

    def parse(text: str):
        try:
            return from_text(name, text)
        except SettingError as e:
            raise argparse.ArgumentTypeError(e.body) from None

    parse.__name__ = name  # argparse names the type in some messages
    return parse


def _help(s: Setting) -> str:
    d = default(s.name)
    acc = describe(s.name)
    extra = f"; accepts {acc}" if acc and s.kind not in ("choice",) else ""
    dflt = f" (default {d})" if d is not None and not isinstance(d, list) else ""
    if isinstance(d, bool):
        dflt = f" (default {str(d).lower()})"
    # On a command line a setting left out is "not given" (None in Python).
    text = s.help.replace("; None: ", "; not given: ")
    return (text + extra + dflt).replace("%", "%%")


#: Settings given elsewhere on the qogi quantify command line (the scene
#: options shared with qogi info/convert/gui: qogi.apps._cli_camera).
_SCENE_OPTIONS = ("distance_m", "ambient_temperature_K", "pressure_Pa")


def add_arguments(parser, skip: Sequence[str] = _SCENE_OPTIONS) -> None:
    """Add one option per setting (its :attr:`Setting.flag`) to an argparse
    parser; the value is checked while the command line is parsed. Each
    option's ``dest`` is the setting's name. ``--wind-speed`` and
    ``--exit-velocity`` also choose that velocity source, and
    ``--infer-temperature`` is ``--gas-temperature infer``."""
    gas = parser.add_mutually_exclusive_group()
    speed = parser.add_mutually_exclusive_group()
    target = {"gas_temperature": gas}
    target.update(dict.fromkeys(("velocity", "wind_speed_m_s", "exit_velocity_m_s"), speed))
    for s in SETTINGS.values():
        if not s.flag or s.name in skip:
            continue
        kw: Dict[str, Any] = dict(dest=s.name, default=None, type=arg_type(s.name))
        if s.kind == "choice":
            kw["metavar"] = "{" + ",".join(choices(s.name)) + "}"
        else:
            kw["metavar"] = s.metavar or None
        if s.name == "species":
            kw["action"] = "append"
        kw["help"] = _help(s)
        target.get(s.name, parser).add_argument(s.flag, **kw)
    gas.add_argument(
        "--infer-temperature",
        dest="gas_temperature",
        action="store_const",
        const="infer",
        help="the same as --gas-temperature infer (needs >= 2 channels)",
    )


def config_overrides(args) -> Dict[str, Any]:
    """The settings given on a command line parsed with :func:`add_arguments`
    (name -> value; a flag not given is left out)."""
    out: Dict[str, Any] = {}
    for s in SETTINGS.values():
        v = getattr(args, s.name, None)
        if v is None:
            continue
        if s.name == "species":  # repeatable, each maybe a list
            v = [sp for group in v for sp in group]
        out[s.name] = v
    if "wind_speed_m_s" in out and "velocity" not in out:
        out["velocity"] = "wind"
    if "exit_velocity_m_s" in out and "velocity" not in out:
        out["velocity"] = "exit"
    return out
