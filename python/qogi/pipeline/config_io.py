"""Settings files: the text of a saved :class:`qogi.QuantifyConfig` (plus the
control surfaces and the reporting unit), read from TOML or a result JSON
(which embeds them) and written as TOML. The file format only: the values
are checked and made into a config by :func:`qogi.pipeline.config.load_settings`.

A settings file (TOML)::

    # qogi quantify settings
    units = "kg/h"                      # reporting unit (qogi.units)
    species = ["CH4"]
    gas_temperature = "ambient"
    velocity = "fluid"
    source = [159.5, 227.0]
    background = {x0 = 10, y0 = 10, x1 = 40, y1 = 40}   # or "beside-surface"

    [[surfaces]]
    name = "S1"
    points = [[100.0, 207.0], [220.0, 207.0]]

Top-level keys are :class:`~qogi.QuantifyConfig` fields (docs/pipeline_api.md),
``units`` and ``surfaces``; a key the config does not know is an error (a
typo must not silently fall back to a default). Keys left out take their
defaults; TOML has no null, so a field whose value is None is left out.
A result JSON (``"format": "qogi-result"``) holds the same under ``config``,
``surfaces`` and ``units``.
"""

from __future__ import annotations

import json
import math
import os
import sys
from typing import Optional

from ..errors import UsageError
from ..files import PathLike, atomic_open

__all__ = ["read_settings_file", "write_toml", "dumps_toml"]


def read_settings_file(path: PathLike) -> dict:
    """The table a settings file holds: a ``.toml`` file or a ``.json`` (a
    result or a plain config dict), parsed but not yet checked. Raises
    UsageError for a missing file or bad syntax, naming the file."""
    p = os.fspath(path)
    try:
        with open(p, "rb") as fh:
            raw = fh.read()
    except OSError as e:
        raise UsageError(f"cannot read settings {p}: {e.strerror or e}") from e
    try:
        if p.lower().endswith(".json") or raw.lstrip()[:1] == b"{":
            d = json.loads(raw.decode("utf-8"))
        else:
            d = _loads_toml(raw.decode("utf-8"))
    except (ValueError, UnicodeDecodeError) as e:
        raise UsageError(f"cannot parse settings {p}: {e}") from e
    return d


def _loads_toml(text: str) -> dict:
    if sys.version_info >= (3, 11):
        import tomllib
    else:
        try:
            import tomli as tomllib
        except ImportError as e:
            raise UsageError(
                "reading TOML on Python < 3.11 needs the package tomli "
                "(pip install tomli), or give the settings as JSON"
            ) from e
    return tomllib.loads(text)


# -- writing TOML (the small subset settings need) ----------------------------


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if not math.isfinite(v):
            raise UsageError(f"TOML settings cannot hold {v}")
        return repr(v)  # shortest string that reads back to the same double
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string is a valid TOML basic string
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return (
            "{"
            + ", ".join(f"{_toml_key(k)} = {_toml_value(x)}" for k, x in v.items() if x is not None)
            + "}"
        )
    raise UsageError(f"cannot write {type(v).__name__} {v!r} to TOML")


def _toml_key(k: str) -> str:
    k = str(k)
    return k if k.replace("_", "").replace("-", "").isalnum() and k.isascii() else json.dumps(k)


def dumps_toml(config, surfaces=(), units: Optional[str] = None) -> str:
    """The settings as TOML text (reads back with :func:`load_settings` to an
    equal config; floats are written in their shortest exact form)."""
    lines = [
        "# qogi quantify settings (docs/pipeline_api.md); replay with",
        "# qogi quantify REC --config THIS.toml",
    ]
    if units:
        lines.append(f"units = {_toml_value(units)}")
    for k, v in config.to_dict().items():
        if v is not None:
            lines.append(f"{_toml_key(k)} = {_toml_value(v)}")
    for s in surfaces:
        lines += [
            "",
            "[[surfaces]]",
            f"name = {_toml_value(s.name)}",
            f"points = {_toml_value([[float(x), float(y)] for x, y in s.points])}",
        ]
    return "\n".join(lines) + "\n"


def write_toml(path: PathLike, config, surfaces=(), units: Optional[str] = None) -> None:
    """Write the settings as TOML (atomically)."""
    text = dumps_toml(config, surfaces, units)
    with atomic_open(path, "w") as fh:
        fh.write(text)
