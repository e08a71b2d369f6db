"""The recording contract's shared rules (docs/recording.md): the format tag and
version, the frame quantities, the accepted ranges of the metadata and the
error every reader, writer and model raises when a file or an object breaks
them. The base of the io layer and of the camera model, so that both check
the same ranges with the same messages.
"""

from __future__ import annotations

import math
import re
from typing import Optional, Tuple

import numpy as np

from .errors import DataError

FORMAT = "qogi-recording"
VERSION = 1
#: Frame quantities and their units.
QUANTITIES = {"radiance": "W/(m2 sr)", "radiometric_temperature": "K"}
#: Accepted closed ranges [low, high] of scalar metadata (a value must be
#: finite; "low" is exclusive where marked by the error message). One table so
#: that the docs, the checks and the messages agree.
RANGES = {
    "camera.ifov_rad": (0.0, 0.1, "rad", "exclusive_low"),
    "camera.frame_rate_hz": (0.0, 1e5, "Hz", "exclusive_low"),
    "camera.netd_K": (0.0, 10.0, "K", "exclusive_low"),
    "scene.distance_m": (0.0, 1e5, "m", "exclusive_low"),
    "scene.ambient_temperature_K": (180.0, 350.0, "K", ""),
    "scene.pressure_Pa": (3.0e4, 1.1e5, "Pa", ""),
    "scene.wind_speed_m_s": (0.0, 100.0, "m/s", ""),
    "scene.gas_temperature_K": (150.0, 2500.0, "K", ""),
    "scene.background_temperature_K": (10.0, 2500.0, "K", ""),
    "truth.emission_rate_kg_s": (0.0, 1e6, "kg/s", ""),
}
#: The /scene attributes a recording must hold, then those it may hold (with
#: the ranges of RANGES["scene.<name>"]).
SCENE_REQUIRED = ("distance_m", "ambient_temperature_K", "pressure_Pa")
SCENE_OPTIONAL = ("wind_speed_m_s", "gas_temperature_K", "background_temperature_K")
#: /camera frame_rate_hz must match 1 / typical_interval(time_s) within this
#: relative tolerance, or opening fails: time_s is what the pipeline uses, and
#: a file whose two clocks disagree by more is ambiguous. (Dropped frames and
#: jitter are fine: see typical_interval.)
FRAME_RATE_TOLERANCE = 0.01

SPECIES_RE = re.compile(r"^[A-Za-z][A-Za-z0-9]*$")
MEMORY = "<in memory>"


class RecordingError(DataError):
    """A recording that does not follow the contract (a
    :class:`qogi.errors.DataError`, hence a ValueError; exit 3 on the command line).

    The message names the file, the dataset or attribute, the offending value,
    the expected form and how to fix it. The parts are also attributes:
    ``path``, ``location``, ``problem``, ``fix``.
    """

    def __init__(self, path: str, location: str, problem: str, fix: str = ""):
        self.path, self.location, self.problem, self.fix = path, location, problem, fix
        msg = f"{path}: {location}: {problem}"
        if fix:
            msg += f". Fix: {fix}"
        super().__init__(msg)


def check_range(key: str, value, path: str, location: str, fix: str = "") -> float:
    lo, hi, unit, mode = RANGES[key]
    name = key.split(".", 1)[1]
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RecordingError(
            path, location, f"{name} must be a number [{unit}]; got {value!r}", fix
        ) from None
    low_ok = v > lo if mode == "exclusive_low" else v >= lo
    if not (math.isfinite(v) and low_ok and v <= hi):
        interval = f"({lo:g}, {hi:g}]" if mode == "exclusive_low" else f"[{lo:g}, {hi:g}]"
        raise RecordingError(
            path,
            location,
            f"{name} = {v!r} {unit} is outside the accepted range {interval} {unit}",
            fix,
        )
    return v


# --------------------------------------------------------------------------- metadata


def damaged(p: str, e: Exception) -> RecordingError:
    """What a failure of HDF5 or numpy while reading an untrusted file becomes
    (h5py raises OSError, KeyError, TypeError, ... on damaged structures)."""
    return RecordingError(
        p,
        "file",
        f"cannot be read ({type(e).__name__}: {e})",
        "the file is damaged or not written by a recording writer; export it again",
    )


# --------------------------------------------------------------------------- frames and times


def first_nonfinite(block: np.ndarray) -> Tuple[int, ...]:
    return tuple(int(v) for v in np.argwhere(~np.isfinite(block))[0])


def validate_time(path: str, t: np.ndarray, n_frames: int, location: str = "/time_s") -> None:
    if t.ndim != 1 or t.shape[0] != n_frames:
        raise RecordingError(
            path,
            location,
            f"expected shape ({n_frames},) to match the {n_frames} frames; got {t.shape}",
            "write one time [s] per frame",
        )
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise RecordingError(
            path,
            location,
            f"{bad.size} non-finite times, the first at index {bad[0]} ({t[bad[0]]!r})",
            "write finite frame times in seconds",
        )
    if n_frames > 1:
        d = np.diff(t)
        bad = np.flatnonzero(d <= 0)
        if bad.size:
            i = int(bad[0])
            raise RecordingError(
                path,
                location,
                f"times must be strictly increasing; time_s[{i}] = {t[i]!r} "
                f"and time_s[{i + 1}] = {t[i + 1]!r} "
                f"({bad.size} such steps)",
                "sort the frames by time and drop duplicates",
            )


def typical_interval(time_s) -> float:
    """The typical frame interval [s] of increasing frame times: the mean of
    the intervals within +-50% of the median one. Robust to dropped frames
    (longer intervals) and to time stamps quantized to e.g. 1 ms (a 30 Hz
    camera stamping 33 and 34 ms intervals), where the plain median is off
    by up to one quantum."""
    d = np.diff(np.asarray(time_s, dtype=np.float64))
    m = float(np.median(d))
    near = d[(d > 0.5 * m) & (d < 1.5 * m)]
    return float(near.mean()) if near.size else m


def frame_rate_from_times(t: np.ndarray) -> float:
    if t.size < 2:
        raise RecordingError(
            MEMORY,
            "camera.frame_rate_hz",
            "cannot infer the frame rate from a single frame time",
            "set camera.frame_rate_hz",
        )
    return 1.0 / typical_interval(t)


def check_frame_rate(path: str, t: np.ndarray, frame_rate_hz: Optional[float]) -> None:
    if frame_rate_hz is None:
        raise RecordingError(
            path, "/camera attr frame_rate_hz", "missing", "write the camera frame rate in Hz"
        )
    if t.size < 2:
        return
    measured = 1.0 / typical_interval(t)
    if abs(measured - frame_rate_hz) > FRAME_RATE_TOLERANCE * frame_rate_hz:
        raise RecordingError(
            path,
            "/camera attr frame_rate_hz",
            f"frame_rate_hz = {frame_rate_hz:g} Hz disagrees with /time_s, whose typical frame "
            f"interval {1.0 / measured:.6g} s means {measured:.6g} Hz "
            f"(tolerance {FRAME_RATE_TOLERANCE:.0%})",
            "correct frame_rate_hz or time_s (time_s is what the pipeline uses)",
        )
