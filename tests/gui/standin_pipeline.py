"""A small stand-in for the quantification pipeline, following docs/pipeline_api.md.

Only for the view-model's unit tests: it exposes the contract's names
(Surface, Region, QuantifyConfig, quantify, Cancelled, Result, ...) with their
documented behaviour (validation raising ValueError naming the field,
progress(fraction, message) -> False cancels with ``Cancelled.partial``), so the
tests can check what the viewer passes and how it reacts, frame by frame and
deterministically. Its numbers are not physics: rates are a fixed per-surface
value times the frame index, recorded so that tests can check the wiring.
"""

from __future__ import annotations

import csv
import json
import math
import threading
from dataclasses import asdict, dataclass, field
from typing import Optional

import numpy as np

import qogi
from qogi import RecordingError, open_recording  # noqa: F401  (re-exported like qogi's)

CALLS = []  # (surfaces, config, keep_maps) of every quantify call, for the tests


class Cancelled(Exception):
    def __init__(self, message, partial=None):
        super().__init__(message)
        self.partial = partial


@dataclass
class Surface:
    points: list
    name: str = ""
    closed: bool = False

    def __post_init__(self):
        pts = [(float(x), float(y)) for x, y in self.points]
        if len(pts) < 2:
            raise ValueError(f"points must hold at least 2 (x, y) pairs; got {len(pts)}")
        self.points = pts


@dataclass
class Region:
    x0: int
    y0: int
    x1: int
    y1: int


@dataclass
class QuantifyConfig:
    species: list = field(default_factory=lambda: ["CH4"])
    gas_temperature: object = "ambient"
    velocity: str = "fluid"
    wind_speed_m_s: Optional[float] = None
    exit_velocity_m_s: Optional[float] = None
    averaging: str = "per-frame"
    background: object = "percentile"
    background_percentile: float = 5.0
    source: Optional[tuple] = None
    distance_m: Optional[float] = None
    ambient_temperature_K: Optional[float] = None
    pressure_Pa: Optional[float] = None
    sigma_m: Optional[float] = None
    frames: Optional[tuple] = None
    num_threads: int = 0

    def __post_init__(self):
        if not self.species:
            raise ValueError("species must name at least one species; got []")
        for s in self.species:
            if s not in ("CH4", "CO2", "C2H6"):
                raise ValueError(f"species {s!r} is not supported; supported: CH4, CO2, C2H6")
        if self.velocity == "wind" and self.wind_speed_m_s is None:
            raise ValueError("wind_speed_m_s must be given when velocity='wind'")
        if not 0 < self.background_percentile < 100:
            raise ValueError(f"background_percentile must be in (0, 100); "
                             f"got {self.background_percentile}")


@dataclass
class SpeciesRate:
    time_s: np.ndarray
    rate_kg_s: np.ndarray
    mean_kg_h: float
    ci90_kg_h: tuple
    mean_g_h: float
    mean_slpm: float
    n_frames: int
    truth_kg_h: Optional[float]
    dominant_uncertainty: str
    uncertainty_terms_kg_h: dict
    pixels_used: np.ndarray


@dataclass
class SurfaceResult:
    surface: Surface
    species: dict


class Result:
    standard_conditions = "293.15 K, 101325 Pa"

    def __init__(self, surfaces, pixel_status, maps, config, path):
        self.surfaces = surfaces
        self.pixel_status = pixel_status
        self._maps = maps
        self.config = config
        self.recording_path = path

    def maps(self, frame):
        if self._maps is None:
            raise ValueError("no maps: run quantify with keep_maps=True")
        if frame not in self._maps:
            raise IndexError(f"frame {frame} was not quantified")
        return self._maps[frame]

    def to_json(self, path=None):
        d = {"surfaces": [{"name": s.surface.name, "points": s.surface.points,
                           "species": {k: {"mean_kg_h": r.mean_kg_h,
                                           "ci90_kg_h": list(r.ci90_kg_h),
                                           "n_frames": r.n_frames,
                                           "time_s": r.time_s.tolist(),
                                           "rate_kg_h": (r.rate_kg_s * 3600).tolist(),
                                           "truth_kg_h": r.truth_kg_h}
                                       for k, r in s.species.items()}}
                          for s in self.surfaces],
             "pixel_status": self.pixel_status}
        text = json.dumps(d, allow_nan=True)
        if path:
            with open(path, "w") as f:
                f.write(text)
        return d

    def to_csv(self, path):
        with open(path, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["surface", "species", "time_s", "rate_kg_h"])
            for s in self.surfaces:
                for sp, r in s.species.items():
                    for t, v in zip(r.time_s, r.rate_kg_s):
                        w.writerow([s.surface.name, sp, f"{t:.6f}", f"{v * 3600:.9g}"])

    def plot(self, path=None, kind="rates"):
        import matplotlib.figure

        fig = matplotlib.figure.Figure(figsize=(4, 3))
        ax = fig.add_subplot()
        for s in self.surfaces:
            for sp, r in s.species.items():
                ax.plot(r.time_s, r.rate_kg_s * 3600, label=f"{s.surface.name} {sp}")
        ax.set_title(kind)
        if path:
            fig.savefig(path)
        return fig

    def summary(self):
        return "\n".join(f"{s.surface.name} {sp}: {r.mean_kg_h:.3g} kg/h"
                         for s in self.surfaces for sp, r in s.species.items())


# The tests set these to control a run: an Event quantify waits on before each
# frame (None = do not wait) and an exception raised at a given frame.
gate: Optional[threading.Event] = None
fail_at: Optional[int] = None
fail_with: Exception = RuntimeError("engine exploded")


def quantify(recording, surfaces, config=None, progress=None, keep_maps=False):
    config = config or QuantifyConfig()
    CALLS.append((surfaces, config, keep_maps))
    if recording.n_frames < 2:
        raise RecordingError(recording.path, "/frames", "fewer than 2 frames")
    start, stop = config.frames or (0, recording.n_frames)
    truth = recording.truth.emission_rate_kg_s if recording.truth is not None else {}
    h, w = recording.height, recording.width
    done, maps = [], {} if keep_maps else None

    def result():
        t = recording.time_s[done] if done else np.zeros(0)
        out = []
        for k, s in enumerate(surfaces):
            sp = {}
            for name in config.species:
                rate = np.array([(k + 1) * 1e-4 * (1 + (f % 3)) for f in done])
                if len(rate) > 2:
                    rate[1] = np.nan  # one frame "could not be quantified"
                m = float(np.nanmean(rate)) * 3600 if np.isfinite(rate).any() else math.nan
                sp[name] = SpeciesRate(t, rate, m, (0.8 * m, 1.2 * m), m * 1e3, m * 25.0,
                                       len(done), truth.get(name, None) and truth[name] * 3600,
                                       "velocity", {"velocity": 0.1 * m},
                                       np.full(len(done), 20))
            out.append(SurfaceResult(s, sp))
        return Result(out, {"converged": 90 * len(done), "at bound": 5 * len(done),
                            "below detection": 4 * len(done), "failed": len(done)},
                      maps, config, recording.path)

    for i, f in enumerate(range(start, stop)):
        if gate is not None:
            gate.wait(10)
        if fail_at is not None and f == fail_at:
            raise fail_with
        done.append(f)
        if keep_maps:
            yy, xx = np.mgrid[0:h, 0:w]
            col = np.exp(-((xx - w / 2) ** 2) / 50.0) * (1e-3 * (1 + f % 3))
            maps[f] = {"column_density_kg_m2": {s: col.astype(np.float32)
                                                for s in config.species},
                       "velocity_px_per_frame": (np.zeros((h, w), np.float32),
                                                 -np.ones((h, w), np.float32)),
                       "status": np.zeros((h, w), np.uint8)}
        if progress is not None and progress((i + 1) / (stop - start),
                                             f"frame {f + 1} of {stop}") is False:
            raise Cancelled("cancelled", result())
    return result()


velocimetry = qogi.velocimetry
