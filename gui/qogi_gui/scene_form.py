"""The viewer's small form for the scene facts a camera file does not hold.

Opening a FLIR or Telops file needs the camera (spectral response) and, for
Telops, the distance and ambient temperature; FLIR files hold a distance and
an atmospheric temperature that may be the camera's factory defaults. The
form asks for them instead of failing; what is entered is remembered per
file (:meth:`qogi_gui.store.UserStore.set_scene`)."""

from __future__ import annotations

import dataclasses
import os
from typing import Dict, List

__all__ = ["SceneRequest", "FIELDS", "parse_facts"]

#: Form fields: key -> (label, unit).
FIELDS = {
    "camera": ("camera", "preset or response CSV"),
    "distance_m": ("distance", "m"),
    "ambient_temperature_K": ("ambient temperature", "K"),
    "pressure_Pa": ("pressure", "Pa"),
}


@dataclasses.dataclass
class SceneRequest:
    """A camera file waiting for its scene facts.

    ``needs``: facts the file does not hold (required); ``holds``: values the
    file holds (used when a field is left empty); ``defaults``: held values
    that are the camera's factory defaults (the form says so); ``values``:
    the form's text per field; ``errors``: message per field; ``error``: why
    the last attempt failed."""

    path: str
    kind: str
    needs: List[str]
    holds: Dict[str, object]
    defaults: List[str]
    values: Dict[str, str]
    errors: Dict[str, str] = dataclasses.field(default_factory=dict)
    error: str = ""

    def hint(self, key: str) -> str:
        """What the form shows beside a field."""
        if key in self.needs:
            return "required: the file does not hold it"
        if key in self.holds and self.holds[key] is not None:
            v = self.holds[key]
            unit = FIELDS[key][1]
            tag = " (the camera's factory default: check it)" if key in self.defaults else ""
            return f"file: {v:g} {unit}{tag}; leave empty to use it"
        if key == "pressure_Pa":
            return "empty: 101325 Pa (sea level), flagged"
        return ""

    @property
    def title(self) -> str:
        return (
            f"{os.path.basename(self.path)}: a "
            f"{self.kind.upper() if self.kind == 'flir' else 'Telops'}"
            " file; give what it does not hold"
        )


def parse_facts(values: Dict[str, str], needs: List[str]):
    """(facts, errors): keyword arguments for ``qogi.open_recording`` from the
    form's text, and a message per bad field."""
    facts, errors = {}, {}
    cam = str(values.get("camera", "") or "").strip()
    if cam:
        facts["camera"] = cam
    elif "camera" in needs:
        errors["camera"] = "give the camera: gf320, fast-m150 or a spectral-response CSV path"
    for key, lo, hi in (
        ("distance_m", 0.0, 1e5),
        ("ambient_temperature_K", 180.0, 350.0),
        ("pressure_Pa", 3e4, 1.1e5),
    ):
        text = str(values.get(key, "") or "").strip()
        if not text:
            if key in needs:
                errors[key] = f"give the {FIELDS[key][0]} [{FIELDS[key][1]}]"
            continue
        try:
            v = float(text)
        except ValueError:
            errors[key] = f"{FIELDS[key][0]} must be a number [{FIELDS[key][1]}]; got {text!r}"
            continue
        if not (lo < v <= hi if key == "distance_m" else lo <= v <= hi):
            errors[key] = f"{FIELDS[key][0]} must be within [{lo:g}, {hi:g}] {FIELDS[key][1]}"
            continue
        facts[key] = v
    return facts, errors
