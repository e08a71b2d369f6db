"""The analysis form: what the technician types, checked field by field.

:class:`AnalysisSettings` keeps every field as the text (or choice) the user
entered, so a bad value stays on screen next to its message instead of being
lost. :meth:`AnalysisSettings.validate` returns one message per field ("" when
the field is fine); :meth:`AnalysisSettings.build_config` turns a valid form
into ``qogi.QuantifyConfig`` (docs/pipeline_api.md), whose own checks are
reported against the field they name.

Every field that is a setting of the run is read and checked by the run's
settings table (``qogi.pipeline.settings``): the same ranges, choices and messages as
the command line, the settings TOML and the batch manifest, so a value the
form accepts is one the run accepts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

__all__ = [
    "AnalysisSettings",
    "FIELDS",
    "GAS_TEMPERATURE_MODES",
    "AVERAGING",
    "BACKGROUNDS",
    "LINE_SHAPE_WINGS",
    "LINE_SHAPE_BROADENINGS",
    "velocity_choices",
    "SettingsError",
]

from qogi.physics.forward import TABLE_WING_CM1, WING_CM1_RANGE
from qogi.pipeline import settings as _settings

GAS_TEMPERATURE_MODES = ("ambient", "given", "infer")
AVERAGING = _settings.choices("averaging")
#: The first is the default, as in ``qogi.QuantifyConfig``.
BACKGROUNDS = _settings.choices("background") + ("region",)
#: Species offered in addition to those the recording's scene names.
COMMON_SPECIES = ("CH4", "CO2")
#: Line-shape rules of the cross-sections (``qogi.physics.forward.LineShape``): the
#: wing rule (a fixed window in cm-1, or HAPI's 50 half-widths) and the
#: broadening (by the gas itself and air, or by air alone). First: the default.
LINE_SHAPE_WINGS = ("fixed", "hapi")
LINE_SHAPE_BROADENINGS = ("self", "air")
#: The fixed wing's half-width [cm-1]: default and accepted range, as
#: ``qogi.physics.forward.LineShape`` checks them.
LINE_WING_CM1_DEFAULT = TABLE_WING_CM1
LINE_WING_CM1_RANGE = WING_CM1_RANGE

#: Field key -> (label, unit). The keys are the form's, not always the config's.
FIELDS: Dict[str, Tuple[str, str]] = {
    "species": ("species", ""),
    "gas_temperature_K": ("gas temperature", "K"),
    "velocity": ("velocity source", ""),
    "wind_speed_m_s": ("wind speed", "m/s"),
    "exit_velocity_m_s": ("exit velocity", "m/s"),
    "averaging": ("averaging order", ""),
    "background": ("background", ""),
    "background_percentile": ("background percentile", "%"),
    "distance_m": ("distance", "m"),
    "ambient_temperature_K": ("ambient temperature", "K"),
    "pressure_Pa": ("pressure", "Pa"),
    "sigma_m": ("plume depth sigma", "m"),
    "exit_temperature_K": ("exit temperature", "K"),
    "line_shape": ("line shape", ""),
    "line_shape_wing_cm1": ("line wing half-width", "cm-1"),
    "frame_start": ("first frame", ""),
    "frame_stop": ("stop frame", ""),
    "num_threads": ("threads", ""),
    "source": ("source position", "px"),
}

# Config field names (as they appear in the pipeline's error messages) -> form field.
_CONFIG_TO_FORM = {
    "species": "species",
    "gas_temperature": "gas_temperature_K",
    "velocity": "velocity",
    "wind_speed_m_s": "wind_speed_m_s",
    "exit_velocity_m_s": "exit_velocity_m_s",
    "averaging": "averaging",
    "background_percentile": "background_percentile",
    "background": "background",
    "source": "source",
    "distance_m": "distance_m",
    "ambient_temperature_K": "ambient_temperature_K",
    "pressure_Pa": "pressure_Pa",
    "sigma_m": "sigma_m",
    "frames": "frame_start",
    "num_threads": "num_threads",
    "exit_temperature_K": "exit_temperature_K",
    "line_shape": "line_shape",
    "line shape": "line_shape",  # qogi.physics.forward.LineShape's own messages
}


class SettingsError(ValueError):
    """The form has invalid fields; ``errors`` maps field -> message."""

    def __init__(self, errors: Dict[str, str]):
        self.errors = {k: v for k, v in errors.items() if v}
        lines = [f"{FIELDS.get(k, (k, ''))[0]}: {v}" for k, v in self.errors.items()]
        super().__init__("; ".join(lines) if lines else "invalid settings")


def velocity_choices() -> List[str]:
    """Velocity sources: the methods of ``qogi.measure.velocimetry`` (default first),
    then ``"wind"`` (a given speed) and ``"exit"`` (a given exit velocity):
    the settings table's choices."""
    methods = list(_settings.choices("velocity"))
    default = _settings.default("velocity")
    methods.sort(key=lambda m: m != default)
    return methods


def _check(name: str, text: str) -> str:
    """ "" if ``text`` is a value the run's setting ``name`` accepts, else
    the settings table's message (qogi.pipeline.settings.from_text)."""
    try:
        _settings.from_text(name, text)
    except _settings.SettingError as e:
        return e.body
    return ""


def _value(name: str, text: str):
    """The value of setting ``name`` typed as ``text`` (valid: checked first)."""
    return _settings.from_text(name, text)


def _number(text: str) -> float:
    s = str(text).strip()
    if not s:
        raise ValueError("empty: type a number")
    try:
        v = float(s)
    except ValueError:
        raise ValueError(f"{s!r} is not a number") from None
    if not math.isfinite(v):
        raise ValueError(f"{s!r} is not a finite number")
    return v


def _integer(text: str) -> int:
    s = str(text).strip()
    try:
        return int(s)
    except ValueError:
        raise ValueError(f"{s!r} is not a whole number") from None


def _hint(name: str) -> str:
    """The numbers the run's setting ``name`` accepts, as the settings
    table states them (``[150, 600] K``, ``>= 0``)."""
    return _settings.SETTINGS[name].range_text()


#: Text fields that are the run's optional numbers (empty: None).
_OPTIONAL_NUMBERS = (
    "distance_m",
    "ambient_temperature_K",
    "pressure_Pa",
    "sigma_m",
    "exit_temperature_K",
)


@dataclass
class AnalysisSettings:
    """The analysis form. Text fields hold what the user typed; an empty
    scene field means "the recording's value" and an empty ``sigma_m`` means
    "from the plume width"."""

    species: Dict[str, bool] = field(default_factory=lambda: {"CH4": True})
    gas_temperature_mode: str = "ambient"
    gas_temperature_K: str = ""
    velocity: str = "fluid"
    wind_speed_m_s: str = ""
    exit_velocity_m_s: str = ""
    averaging: str = "per-frame"
    background: str = BACKGROUNDS[0]
    background_percentile: str = "5"
    distance_m: str = ""
    ambient_temperature_K: str = ""
    pressure_Pa: str = ""
    sigma_m: str = ""
    #: The gas's temperature at the exit [K], when known (empty: not known).
    exit_temperature_K: str = ""
    line_shape_wing: str = LINE_SHAPE_WINGS[0]
    line_shape_wing_cm1: str = f"{LINE_WING_CM1_DEFAULT:g}"
    line_shape_broadening: str = LINE_SHAPE_BROADENINGS[0]
    frame_start: str = "0"
    frame_stop: str = ""
    num_threads: str = "0"
    use_source: bool = False
    source_x: str = ""
    source_y: str = ""
    #: Keep per-pixel maps (column density, velocity, status) for the overlay.
    keep_maps: bool = True

    # ----------------------------------------------------------------- defaults
    @classmethod
    def for_recording(cls, recording) -> AnalysisSettings:
        """Defaults for a recording: its scene's species (or CH4) ticked, its
        scene values as the scene fields, all frames."""
        scene = recording.scene
        names = list(dict.fromkeys(list(scene.species) + list(COMMON_SPECIES)))
        ticked = set(scene.species) or {"CH4"}
        s = cls(species={n: n in ticked for n in names})
        s.distance_m = f"{scene.distance_m:g}"
        s.ambient_temperature_K = f"{scene.ambient_temperature_K:g}"
        s.pressure_Pa = f"{scene.pressure_Pa:g}"
        if scene.gas_temperature_K is not None:
            s.gas_temperature_K = f"{scene.gas_temperature_K:g}"
        if scene.wind_speed_m_s is not None:
            s.wind_speed_m_s = f"{scene.wind_speed_m_s:g}"
        s.frame_stop = str(recording.n_frames)
        return s

    def hints(self, recording=None) -> Dict[str, str]:
        """What each field accepts (unit and range), shown beside it."""
        h = {
            "species": "tick at least one",
            "gas_temperature_K": _hint("gas_temperature"),
            "velocity": "optical-flow method, or a given wind / exit speed",
            "wind_speed_m_s": _hint("wind_speed_m_s") + ", along each surface's normal",
            "exit_velocity_m_s": _hint("exit_velocity_m_s") + " (flow / exit area; lab checks)",
            "averaging": "invert each frame, or the time-averaged frames",
            "background": "how the gas-free radiance is estimated",
            "background_percentile": _hint("background_percentile") + ", temporal low percentile",
            "distance_m": _hint("distance_m") + "; empty = recording's",
            "ambient_temperature_K": _hint("ambient_temperature_K") + "; empty = recording's",
            "pressure_Pa": _hint("pressure_Pa") + "; empty = recording's",
            "sigma_m": _hint("sigma_m") + "; empty = from the plume width",
            "exit_temperature_K": (
                _hint("exit_temperature_K") + "; the gas's temperature "
                "at the exit, when known: checks an assumed (ambient or "
                "given) gas temperature, warning gas-temperature-suspect; "
                "empty = not known"
            ),
            "line_shape": (
                "wing rule (fixed window or HAPI's 50 half-widths) and broadening "
                "(self + air, or air only) of the cross-sections; default fixed "
                f"{LINE_WING_CM1_DEFAULT:g} cm-1 + self (docs/forward_model.md); the "
                "budget's 'line shape' term is the spread between the rules"
            ),
            "line_shape_wing_cm1": (
                f"[{LINE_WING_CM1_RANGE[0]:g}, {LINE_WING_CM1_RANGE[1]:g}] "
                "cm-1, the fixed window around each line"
            ),
            "frame_start": "0 ..",
            "frame_stop": "empty = to the end",
            "num_threads": _hint("num_threads") + " (0 = all cores)",
            "source": "x, y in pixels; flow away from it counts positive",
        }
        if recording is not None:
            t = recording.n_frames
            h["frame_start"] = f"0 .. {t - 2}"
            h["frame_stop"] = f"2 .. {t}; empty = to the end ({t})"
            h["source"] = (
                f"x in [-0.5, {recording.width - 0.5}], y in [-0.5, "
                f"{recording.height - 0.5}] px; flow away from it counts positive"
            )
        return h

    # ----------------------------------------------------------------- checks
    def validate(self, recording, region=None, n_surfaces: Optional[int] = None) -> Dict[str, str]:
        """One message per field ("" when fine), against ``recording``
        (channels, frames, image size) and the picked background ``region``."""
        err = dict.fromkeys(FIELDS, "")
        if not any(self.species.values()):
            err["species"] = "tick at least one species"
        if self.gas_temperature_mode not in GAS_TEMPERATURE_MODES:
            err["gas_temperature_K"] = f"choose one of {', '.join(GAS_TEMPERATURE_MODES)}"
        elif self.gas_temperature_mode == "given":
            err["gas_temperature_K"] = _check("gas_temperature", self.gas_temperature_K)
        elif (
            self.gas_temperature_mode == "infer"
            and recording is not None
            and recording.n_channels < 2
        ):
            err["gas_temperature_K"] = (
                f"inferring it needs >= 2 channels; this recording has "
                f"{recording.n_channels}: choose ambient or given"
            )
        choices = velocity_choices()
        if self.velocity not in choices:
            err["velocity"] = f"choose one of {', '.join(choices)}"
        elif self.velocity == "wind":
            err["wind_speed_m_s"] = _check("wind_speed_m_s", self.wind_speed_m_s)
        elif self.velocity == "exit":
            err["exit_velocity_m_s"] = _check("exit_velocity_m_s", self.exit_velocity_m_s)
        if self.averaging not in AVERAGING:
            err["averaging"] = f"choose one of {', '.join(AVERAGING)}"
        if self.background not in BACKGROUNDS:
            err["background"] = f"choose one of {', '.join(BACKGROUNDS)}"
        elif self.background in ("percentile", "drifting"):
            err["background_percentile"] = _check(
                "background_percentile", self.background_percentile
            )
        elif self.background == "region":
            if region is None:
                err["background"] = "pick the region on the image first (Surfaces tab)"
            elif region.n_pixels < 1:
                err["background"] = "the picked region holds no pixel: pick a larger one"
        for name in _OPTIONAL_NUMBERS:  # empty: the recording's (or not known)
            if str(getattr(self, name)).strip():
                err[name] = _check(name, getattr(self, name))
        err["line_shape"], err["line_shape_wing_cm1"] = self._check_line_shape()
        err["frame_start"], err["frame_stop"] = self._check_frames(recording)
        err["num_threads"] = _check("num_threads", self.num_threads)
        if self.use_source:
            err["source"] = self._check_source(recording)
        return err

    def _check_line_shape(self) -> Tuple[str, str]:
        """Messages of the line-shape rule and of the fixed wing's width."""
        if self.line_shape_wing not in LINE_SHAPE_WINGS:
            return f"choose the wing rule: {', '.join(LINE_SHAPE_WINGS)}", ""
        if self.line_shape_broadening not in LINE_SHAPE_BROADENINGS:
            return f"choose the broadening: {', '.join(LINE_SHAPE_BROADENINGS)}", ""
        if self.line_shape_wing != "fixed":
            return "", ""
        try:
            _number(self.line_shape_wing_cm1)
        except ValueError as e:
            return "", str(e)
        return "", _check("line_shape", self.line_shape())

    def line_shape(self) -> str:
        """The rule in ``qogi.QuantifyConfig.line_shape``'s text form
        (``"fixed:25+self"``, ``"hapi+air"``) of a valid form."""
        wing = (
            f"fixed:{_number(self.line_shape_wing_cm1):g}"
            if self.line_shape_wing == "fixed"
            else self.line_shape_wing
        )
        return f"{wing}+{self.line_shape_broadening}"

    def _frame_range(self, recording) -> Tuple[int, int]:
        start = _integer(self.frame_start) if str(self.frame_start).strip() else 0
        n = recording.n_frames if recording is not None else None
        stop = _integer(self.frame_stop) if str(self.frame_stop).strip() else n
        return start, stop

    def _check_frames(self, recording) -> Tuple[str, str]:
        try:
            start = _integer(self.frame_start) if str(self.frame_start).strip() else 0
        except ValueError as e:
            return str(e), ""
        try:
            stop = _integer(self.frame_stop) if str(self.frame_stop).strip() else None
        except ValueError as e:
            return "", str(e)
        if stop is not None or start < 0:  # the run's own check of the range
            msg = _check("frames", f"{start}:{stop if stop is not None else max(start + 1, 1)}")
            if msg:
                return (msg, "") if start < 0 else ("", msg)
        if recording is None:
            return "", ""
        n = recording.n_frames
        stop = n if stop is None else stop
        if stop > n:
            return "", f"{stop} is beyond the last frame: the recording has {n} frames"
        if stop - start < 2:
            return "", (
                f"frames {start}..{stop - 1} are fewer than 2: velocity needs at least two frames"
            )
        return "", ""

    def _check_source(self, recording) -> str:
        msg = _check("source", f"{self.source_x},{self.source_y}")
        if msg:
            return f"{msg} (pick the source on the image or type x and y)"
        try:
            x, y = _number(self.source_x), _number(self.source_y)
        except ValueError as e:
            return f"{e} (pick the source on the image or type x and y)"
        if recording is not None and not (
            -0.5 <= x <= recording.width - 0.5 and -0.5 <= y <= recording.height - 0.5
        ):
            return (
                f"({x:g}, {y:g}) is outside the image (x in [-0.5, "
                f"{recording.width - 0.5}], y in [-0.5, {recording.height - 0.5}])"
            )
        return ""

    # ----------------------------------------------------------------- config
    def config_kwargs(self, api, recording, region=None) -> dict:
        """Keyword arguments of ``api.QuantifyConfig`` for a valid form
        (raises :class:`SettingsError` otherwise)."""
        errors = self.validate(recording, region)
        if any(errors.values()):
            raise SettingsError(errors)
        kw: dict = {"species": [s for s, on in self.species.items() if on]}
        if self.gas_temperature_mode == "given":
            kw["gas_temperature"] = _value("gas_temperature", self.gas_temperature_K)
        else:
            kw["gas_temperature"] = self.gas_temperature_mode
        kw["velocity"] = self.velocity
        if self.velocity == "wind":
            kw["wind_speed_m_s"] = _value("wind_speed_m_s", self.wind_speed_m_s)
        if self.velocity == "exit":
            kw["exit_velocity_m_s"] = _value("exit_velocity_m_s", self.exit_velocity_m_s)
        kw["averaging"] = self.averaging
        if self.background == "region":
            kw["background"] = api.Region(*region.as_tuple())
        else:
            kw["background"] = self.background
        if self.background in ("percentile", "drifting"):
            kw["background_percentile"] = _value(
                "background_percentile", self.background_percentile
            )
        if self.use_source:
            kw["source"] = (_number(self.source_x), _number(self.source_y))
        for name in _OPTIONAL_NUMBERS:
            text = str(getattr(self, name)).strip()
            kw[name] = _value(name, text) if text else None
        kw["line_shape"] = self.line_shape()
        start, stop = self._frame_range(recording)
        if recording is not None and (start, stop) != (0, recording.n_frames):
            kw["frames"] = (start, stop)
        kw["num_threads"] = _value("num_threads", self.num_threads)
        return kw

    def build_config(self, api, recording, region=None):
        """``api.QuantifyConfig`` of the form. Raises :class:`SettingsError`
        with per-field messages (including the config's own checks, matched to
        the field its message names)."""
        kw = self.config_kwargs(api, recording, region)
        try:
            return api.QuantifyConfig(**kw)
        except _settings.SettingError as e:
            field = _CONFIG_TO_FORM.get(e.name) or _field_named_in(str(e))
            raise SettingsError({field: e.body}) from e
        except (ValueError, TypeError) as e:
            raise SettingsError({_field_named_in(str(e)): str(e)}) from e


def _field_named_in(message: str) -> str:
    """The form field whose config name appears first in ``message``
    ("species" if none does, so the message still shows)."""
    best, pos = "species", len(message) + 1
    # Longer names first so "background_percentile" wins over "background".
    for name in sorted(_CONFIG_TO_FORM, key=len, reverse=True):
        i = message.find(name)
        if 0 <= i < pos:
            best, pos = _CONFIG_TO_FORM[name], i
    return best
