"""The operating envelope: a grid of synthetic releases with exact truth,
quantified with qogi's defaults (``qogi envelope``; docs/validation/envelope.md).

A **grid** (TOML) names values for each axis of a release scene:

==============  =====  ===============================================
axis            unit   meaning
==============  =====  ===============================================
``rate_kg_h``   kg/h   the release rate (CH4)
``distance_m``  m      camera to plume
``contrast_K``  K      gas minus background radiometric temperature
                       (> 0 emission, < 0 absorption)
``wind_m_s``    m/s    crosswind, left to right (0: a still lab)
``background``         ``plate``, ``sky`` or ``structured``
``camera``             a camera preset (``gf320`` one channel,
                       ``fast-m150`` four channels)
``duration_s``  s      the record length
``seed``               turbulence and noise
==============  =====  ===============================================

``[base]`` gives every axis one value or a list; each ``[[block]]`` replaces
some axes (a list, or ``{log = [lo, hi, n]}`` for ``n`` log-spaced values);
the cells are the union over blocks of the Cartesian product of the block's
values (the base alone when there are no blocks), duplicates dropped. Three
settings that are not axes sit in ``[base]`` only: ``surfaces_px`` (where the
control surfaces cross the mean plume axis, px of arc length from the exit),
``width_px`` and ``height_px`` (the frame; default the camera's).

**Scenes.** A still cell (``wind_m_s = 0``) is the GF320 lab release
(``lab-ch4-5slpm-gf320``: a 1.9 cm exit at floor level, a 0.02 m/s draft);
a windy cell the stack release (``stack-10kgh-wind4-sky-gf320``: a 6 cm
outlet on a 3.18 m stack, 20 % turbulence), each with only the axes changed,
except that the windy scene's outlet narrows for small rates so the gas
leaves at :data:`MIN_EXIT_SPEED_M_S` (no narrower than
:data:`MIN_EXIT_DIAMETER_M`): a small leak is a small hole, and a 6 cm outlet
at 1 g/h stalls the plume model.
The gas is at the ambient temperature; the background is set to
``T_gas - contrast_K``: a uniform ``plate``; a ``sky`` whose apparent
temperature rises by ``|contrast| / 2`` from the top row to the bottom (the
contrast shrinks towards the horizon but never changes sign); a
``structured`` wall with the seams, bolts, shadow edge and texture of the
``stack-5kgh-wind3-tank-emission-gf320`` preset (real structure does not
scale with the contrast). The frame keeps the preset's exit position as
fractions of the frame. The camera sees the plume at ``distance_m`` with its
own pixel size.

Cells the simulator cannot express physically are left out and listed with
the reason (:func:`load_grid`): a plate that does not fill the frame (a lab
backdrop :data:`PLATE_SIZE_M` across), a sky warmer than the gas, an exit
faster than 0.3 of the speed of sound (the plume model is incompressible),
a control surface outside the frame.

**Quantification** (:func:`run`): each cell and seed is rendered once
(``OUTDIR/renders``), then every rendering is quantified by
:func:`qogi.apps.batch.run` (one Dask task each, ``OUTDIR/batch``) with the
defaults, the exit given as the source and straight control surfaces
perpendicular to the simulator's mean plume axis at ``surfaces_px`` along it
(long enough for 6 of its concentration widths plus 10 px).

**Signal-to-noise of the scene** (per surface): the true rate over the rate
whose peak column equals the camera's noise-equivalent column,

    ``snr = Q_true / (NEC v w)``

with ``NEC`` the noise-equivalent column [kg/m2] (the most sensitive
channel's, :mod:`qogi.pipeline.detection`), ``v`` the gas speed normal to the
surface and ``w`` the plume's effective width along it, the simulator's mean
plume's (:func:`surface_truth`), so that a run whose velocity is off does
not move its own place on the axis; ``snr_measured`` takes ``v`` and ``w``
as the result's detection record measured them. It is the mean plume's peak
column in units of the noise; the stated detection limit sits at ``snr`` =
``k + z`` (3 + 1.64 at the defaults).
"""

from __future__ import annotations

import csv
import dataclasses
import itertools
import json
import math
import os
import pathlib
import re
import sys
from importlib import resources
from typing import Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

from .. import synth
from .._progress import ProgressBar
from ..errors import UsageError
from ..files import atomic_open, atomic_path
from ..physics.presets import camera_preset, camera_preset_names
from ..pipeline.config_io import _loads_toml
from ..synth import render
from . import batch

__all__ = [
    "AXES",
    "GRIDS",
    "Cell",
    "Grid",
    "load_grid",
    "excluded_scenes",
    "scene",
    "surfaces",
    "render_cell",
    "write_manifest",
    "scene_snr",
    "surface_truth",
    "cell_rows",
    "aggregate",
    "run",
    "plot",
]

#: The still scene (wind 0) and the windy one (wind > 0) the cells vary.
LAB_PRESET = "lab-ch4-5slpm-gf320"
STACK_PRESET = "stack-10kgh-wind4-sky-gf320"
#: The structured background's features (seams, bolts, shadow, texture).
STRUCTURED_PRESET = "stack-5kgh-wind3-tank-emission-gf320"
#: The slowest exit of the windy scene [m/s] and its narrowest outlet [m]: a
#: small leak in wind is a small hole (a 6 cm outlet at 1 g/h makes the plume
#: model creep along in minute steps; below 2 cm it needs 10^4 puffs per second).
MIN_EXIT_SPEED_M_S = 1.0
MIN_EXIT_DIAMETER_M = 0.02
#: A lab backdrop's size [m]: a plate cell needs the frame to fit on it.
PLATE_SIZE_M = 2.0
#: The fastest exit the plume model holds, as a fraction of the speed of sound.
MAX_EXIT_MACH = 0.3
#: The built-in grids (``qogi envelope default``).
GRIDS = ("default", "small")

#: Axis: (unit, smallest, largest) for numbers, or the tuple of choices.
AXES: Dict[str, tuple] = {
    "rate_kg_h": ("kg/h", 1e-4, 1000.0),
    "distance_m": ("m", 0.5, 100.0),
    "contrast_K": ("K", -60.0, 60.0),
    "wind_m_s": ("m/s", 0.0, 15.0),
    "background": ("plate", "sky", "structured"),
    "camera": (),  # the camera presets, filled on use
    "duration_s": ("s", 0.2, 120.0),
    "seed": ("", 0, 2**31 - 1),
}
#: Settings of the whole grid ([base] only): (unit, smallest, largest).
SETTINGS: Dict[str, tuple] = {
    "surfaces_px": ("px", 2.0, 2000.0),
    "width_px": ("px", 16, 4096),
    "height_px": ("px", 16, 4096),
}
_DEFAULT_SURFACES_PX = (30.0, 45.0, 60.0)


@dataclasses.dataclass(frozen=True)
class Cell:
    """One release scene of the grid and one seed (a rendering)."""

    rate_kg_h: float
    distance_m: float
    contrast_K: float
    wind_m_s: float
    background: str
    camera: str
    duration_s: float
    seed: int
    surfaces_px: Tuple[float, ...] = _DEFAULT_SURFACES_PX
    width_px: Optional[int] = None
    height_px: Optional[int] = None
    block: str = ""

    @property
    def name(self) -> str:
        """A file-safe name that says what the cell is (``0.2kgh-1.5m-dT+9.3K-...``)."""
        sign = "p" if self.contrast_K >= 0 else "m"
        frame = f"-{self.width_px}x{self.height_px}" if self.width_px else ""
        return (
            f"{self.rate_kg_h:.4g}kgh-{self.distance_m:g}m-dT{sign}{abs(self.contrast_K):g}K-"
            f"wind{self.wind_m_s:g}-{self.background}-{self.camera}-{self.duration_s:g}s"
            f"{frame}-seed{self.seed}"
        )

    @property
    def scene(self) -> str:
        """The cell without its seed (what the seeds are aggregated over)."""
        return self.name.rsplit("-seed", 1)[0]

    def axes(self) -> dict:
        return {k: getattr(self, k) for k in AXES}


@dataclasses.dataclass
class Grid:
    """A grid read from TOML: its cells and the ones left out with the reason."""

    name: str
    cells: List[Cell]
    excluded: List[Tuple[Cell, str]]
    description: str = ""


def _grid_path(grid: Union[str, os.PathLike]) -> Tuple[str, str]:
    """(name, TOML text) of a built-in grid name or a file."""
    if str(grid) in GRIDS:
        text = resources.files("qogi").joinpath(f"data/envelope_{grid}.toml").read_text()
        return str(grid), text
    p = pathlib.Path(grid)
    if not p.is_file():
        raise UsageError(
            f"grid {grid}: no such file and not a built-in grid; give a TOML file "
            f"or one of {', '.join(GRIDS)}"
        )
    try:
        return p.stem, p.read_text()
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"grid {p}: cannot read it ({e})") from e


def _values(where: str, axis: str, v) -> list:
    """An axis's values as a list, checked against the axis's range/choices."""
    if isinstance(v, dict):
        if set(v) != {"log"} or not isinstance(v["log"], list) or len(v["log"]) != 3:
            raise UsageError(
                f"{where}: {axis} = {v!r}: a table must be {{log = [lo, hi, n]}} "
                "(n log-spaced values from lo to hi)"
            )
        lo, hi, n = v["log"]
        if not (isinstance(n, int) and n >= 1) or not (
            isinstance(lo, (int, float)) and isinstance(hi, (int, float)) and 0 < lo <= hi
        ):
            raise UsageError(
                f"{where}: {axis} log = {v['log']!r}: needs 0 < lo <= hi and an integer n >= 1"
            )
        v = [float(x) for x in np.geomspace(lo, hi, n)]
    vals = v if isinstance(v, list) else [v]
    if not vals:
        raise UsageError(f"{where}: {axis} has no values; give at least one")
    spec = AXES[axis] if axis in AXES else SETTINGS[axis]
    out: List[Union[str, int, float]] = []
    for x in vals:
        if axis in ("background", "camera"):
            choices = camera_preset_names() if axis == "camera" else spec
            if x not in choices:
                raise UsageError(
                    f"{where}: {axis} = {x!r} is not one of {', '.join(choices)}; choose one"
                )
            out.append(str(x))
            continue
        unit, lo, hi = spec
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise UsageError(f"{where}: {axis} = {x!r} is not a number; give a number in {unit}")
        if axis in ("seed", "width_px", "height_px") and int(x) != x:
            raise UsageError(f"{where}: {axis} = {x!r} must be a whole number")
        if not lo <= x <= hi:
            raise UsageError(
                f"{where}: {axis} = {x:g} {unit} is out of range; choose within "
                f"[{lo:g}, {hi:g}] {unit}"
            )
        out.append(int(x) if axis in ("seed", "width_px", "height_px") else float(x))
    return out


def load_grid(grid: Union[str, os.PathLike]) -> Grid:
    """Read and expand a grid: a built-in name (:data:`GRIDS`) or a TOML file.

    Raises
    ------
    UsageError
        Not TOML, an unknown key or axis, a value that is not a number or is
        out of its axis's range, an unknown background or camera.
    """
    name, text = _grid_path(grid)
    try:
        doc = _loads_toml(text)
    except ValueError as e:
        raise UsageError(f"grid {grid}: not valid TOML ({e})") from e
    unknown = sorted(set(doc) - {"description", "base", "block"})
    if unknown:
        raise UsageError(
            f"grid {grid}: unknown top-level key(s) {', '.join(unknown)}; a grid has "
            "description, [base] and [[block]] tables"
        )
    base = doc.get("base", {})
    blocks = doc.get("block", [])
    if not isinstance(base, dict) or not isinstance(blocks, list):
        raise UsageError(f"grid {grid}: [base] must be a table and blocks [[block]] tables")
    known = set(AXES) | set(SETTINGS)
    for where, table in [("[base]", base)] + [
        (f"[[block]] #{k + 1}", b) for k, b in enumerate(blocks)
    ]:
        if not isinstance(table, dict):
            raise UsageError(f"grid {grid}: {where} must be a table")
        bad = sorted(set(table) - known - ({"name"} if where != "[base]" else set()))
        if bad:
            raise UsageError(
                f"grid {grid}: {where}: unknown axis {', '.join(bad)}; axes: "
                f"{', '.join(AXES)}; settings ([base] only): {', '.join(SETTINGS)}"
            )
        if where != "[base]" and set(table) & set(SETTINGS):
            raise UsageError(
                f"grid {grid}: {where}: {', '.join(sorted(set(table) & set(SETTINGS)))} "
                "belong(s) in [base] (a setting of the whole grid)"
            )
    missing = [a for a in AXES if a not in base]
    if missing:
        raise UsageError(f"grid {grid}: [base] lacks {', '.join(missing)}; give every axis a value")
    settings = {
        "surfaces_px": tuple(
            _values(f"grid {grid} [base]", "surfaces_px", base.get("surfaces_px", []))
            if "surfaces_px" in base
            else _DEFAULT_SURFACES_PX
        ),
        "width_px": None,
        "height_px": None,
    }
    for key in ("width_px", "height_px"):
        if key in base:
            (settings[key],) = _values(f"grid {grid} [base]", key, base[key])
    if (settings["width_px"] is None) != (settings["height_px"] is None):
        raise UsageError(f"grid {grid}: [base] gives width_px and height_px together or neither")
    cells: Dict[Cell, Cell] = {}  # without its block label -> labelled (first block wins)
    for k, block in enumerate(blocks or [{}]):
        where = f"grid {grid} [[block]] #{k + 1}" if blocks else f"grid {grid} [base]"
        axes = {a: _values(where, a, block.get(a, base[a])) for a in AXES}
        label = str(block.get("name", f"block {k + 1}" if blocks else "base"))
        for combo in itertools.product(*axes.values()):
            c = Cell(**dict(zip(axes, combo)), **settings)  # type: ignore[arg-type]
            cells.setdefault(c, dataclasses.replace(c, block=label))
    kept, excluded = [], []
    for c in cells.values():
        why = _not_expressible(c)
        if why:
            excluded.append((c, why))
        else:
            kept.append(c)
    return Grid(name, kept, excluded, str(doc.get("description", "")))


def excluded_scenes(g: Grid) -> List[Tuple[str, str]]:
    """The cells left out, once per scene (all seeds), with the reason."""
    return list({c.scene: why for c, why in g.excluded}.items())


# -- the scene of a cell ------------------------------------------------------


def _preset_of(cell: Cell) -> dict:
    return synth.preset(LAB_PRESET if cell.wind_m_s == 0 else STACK_PRESET)


def scene(cell: Cell):
    """The cell's (release, view, background, camera, camera preset name)."""
    p = _preset_of(cell)
    cam = camera_preset(cell.camera)
    w = cell.width_px or cam.width or p["camera"]["width_px"]
    h = cell.height_px or cam.height or p["camera"]["height_px"]
    rel = synth.Release(**p["release"]).replace(
        rate=float(cell.rate_kg_h), rate_unit="kg/h", wind_speed_m_s=float(cell.wind_m_s)
    )
    if cell.wind_m_s > 0:
        d = _exit_diameter_m(rel)
        if d < rel.exit_diameter_m:
            rel = rel.replace(exit_diameter_m=d)
    pw, ph = p["camera"]["width_px"], p["camera"]["height_px"]
    ex, ey = p["scene"]["exit_pixel"]
    exit_px = ((ex + 0.5) / pw * w - 0.5, (ey + 0.5) / ph * h - 0.5)
    view = synth.View.framing(
        rel,
        exit_px,
        width_px=int(w),
        height_px=int(h),
        ifov_rad=float(cam.ifov_rad),
        distance_m=float(cell.distance_m),
        projection="orthographic",
    )
    t_bg = float(rel.exit_temperature_K) - cell.contrast_K
    if cell.background == "plate":
        bg = render.Background("plate", t_bg, seed=cell.seed)
    elif cell.background == "sky":
        half = abs(cell.contrast_K) / 4.0
        bg = render.Background(
            "sky", None, sky_top_K=t_bg - half, sky_bottom_K=t_bg + half, seed=cell.seed
        )
    else:
        features = synth.preset(STRUCTURED_PRESET)["scene"]["background"]
        bg = render.Background.from_dict(dict(features, temperature_K=t_bg), seed=cell.seed)
    return rel, view, bg, cam


def _exit_diameter_m(rel) -> float:
    """The outlet whose exit speed is :data:`MIN_EXIT_SPEED_M_S` (at least
    :data:`MIN_EXIT_DIAMETER_M`): ``sqrt(4 Q / (pi rho v))``."""
    rho = rel.pressure_Pa * _M_CH4 / (_R_GAS * rel.exit_temperature_K)
    flow_m3_s = rel.mass_rate_kg_s() / rho
    return max(MIN_EXIT_DIAMETER_M, math.sqrt(4.0 * flow_m3_s / (math.pi * MIN_EXIT_SPEED_M_S)))


_R_GAS = 8.314462618  # J/(mol K)
_M_CH4 = 0.01604246  # kg/mol
_GAMMA_CH4 = 1.304  # heat capacity ratio at 20 C


def _exit_mach(rel) -> float:
    """Exit speed over the speed of sound of pure CH4 at the exit temperature."""
    rho = rel.pressure_Pa * _M_CH4 / (_R_GAS * rel.exit_temperature_K)
    speed = rel.mass_rate_kg_s() / rho / (math.pi * rel.exit_diameter_m**2 / 4.0)
    return speed / math.sqrt(_GAMMA_CH4 * _R_GAS * rel.exit_temperature_K / _M_CH4)


def surfaces(cell: Cell, rel=None, view=None) -> Tuple[List[list], Tuple[float, float]]:
    """The control surfaces (polylines [px]) and the exit pixel of a cell.

    Each surface is straight, perpendicular to the simulator's mean plume axis
    (:func:`qogi.synth.mean_flow`) where the axis has run ``d`` px (each of
    ``cell.surfaces_px``) from the exit, centred on it, ``6 sigma_c + 10`` px
    long on each side (``sigma_c`` the mean concentration width there), at
    least 20 px. Raises ValueError when a surface's centre falls outside the
    frame; its ends are cut at the frame's edge."""
    if rel is None or view is None:
        rel, view, _, _ = scene(cell)
    fp = view.distance_m * view.ifov_rad
    cx, cy = 0.5 * (view.width_px - 1), 0.5 * (view.height_px - 1)
    ex = cx + (rel.exit_x_m - view.center_x_m) / fp
    ey = cy - (rel.stack_height_m - view.center_z_m) / fp
    out = []
    for d, at in zip(cell.surfaces_px, _mean_axis(cell, rel, view)):
        x = ex + (at("x_m") - rel.exit_x_m) / fp
        y = ey - (at("z_m") - rel.stack_height_m) / fp
        tx, ty = at("tangent_x"), -at("tangent_z")
        norm = math.hypot(tx, ty) or 1.0
        nx, ny = -ty / norm, tx / norm
        half = max(20.0, 6.0 * at("sigma_c_m") / fp + 10.0)
        if not (0 <= x <= view.width_px - 1 and 0 <= y <= view.height_px - 1):
            raise ValueError(f"the surface {d:g} px from the exit is outside the frame")
        ends = []
        for sgn in (-1.0, 1.0):
            # cut at the frame's edge: the largest t <= half inside it
            t = half
            for c0, dc, size in ((x, sgn * nx, view.width_px), (y, sgn * ny, view.height_px)):
                if dc > 1e-12:
                    t = min(t, (size - 1 - c0) / dc)
                elif dc < -1e-12:
                    t = min(t, -c0 / dc)
            ends.append((x + sgn * t * nx, y + sgn * t * ny))
        out.append([round(v, 2) for xy in ends for v in xy])
    return out, (round(ex, 2), round(ey, 2))


def _mean_axis(cell: Cell, rel, view) -> List[Callable[[str], float]]:
    """Per surface distance (``cell.surfaces_px``), a lookup of the
    simulator's mean plume (:func:`qogi.synth.mean_flow`) where its axis has
    run that far from the exit: ``at(key)``. Raises ValueError when the axis
    ends before."""
    fp = view.distance_m * view.ifov_rad
    extent = 1.5 * max(cell.surfaces_px) * fp + 0.1
    mf = synth.mean_flow(rel, extent_m=extent)
    s_px = np.asarray(mf["s_m"]) / fp

    def lookup(d: float) -> Callable[[str], float]:
        def at(key: str) -> float:
            return float(np.interp(d, s_px, np.asarray(mf[key])))

        return at

    out: List[Callable[[str], float]] = []
    for d in cell.surfaces_px:
        if d > s_px[-1]:
            raise ValueError(
                f"the mean plume axis ends {s_px[-1]:.0f} px from the exit, before {d:g} px"
            )
        out.append(lookup(d))
    return out


def surface_truth(cell: Cell, rel=None, view=None) -> List[Tuple[float, float]]:
    """The true mean plume at each of the cell's surfaces: ``(speed_m_s,
    width_m)``, the mass-weighted speed along the axis (the surfaces are
    perpendicular to it, so it is the normal speed) and the effective width
    ``sqrt(2 pi) sigma_c`` of the mean column profile across it (``sum c dl /
    max c`` of a Gaussian of the mean concentration width ``sigma_c``)."""
    if rel is None or view is None:
        rel, view, _, _ = scene(cell)
    return [
        (at("mass_weighted_speed_m_s"), math.sqrt(2.0 * math.pi) * at("sigma_c_m"))
        for at in _mean_axis(cell, rel, view)
    ]


def _not_expressible(cell: Cell) -> Optional[str]:
    """Why the simulator cannot render this cell physically (None: it can)."""
    if cell.background == "sky" and cell.contrast_K <= 0:
        return (
            "a sky as warm as or warmer than gas at the ambient temperature is not a physical sky"
        )
    try:
        rel, view, _, _ = scene(cell)
    except ValueError as e:
        return f"the simulator refuses the scene ({e})"
    if cell.background == "plate":
        size = view.distance_m * view.ifov_rad * max(view.width_px, view.height_px)
        if size > PLATE_SIZE_M:
            return (
                f"a lab plate {PLATE_SIZE_M:g} m across does not fill a {size:.1f} m frame "
                f"at {cell.distance_m:g} m"
            )
    mach = _exit_mach(rel)
    if mach > MAX_EXIT_MACH:
        return (
            f"the exit speed is {mach:.2f} of the speed of sound (> {MAX_EXIT_MACH}); the "
            "plume model is incompressible"
        )
    try:
        surfaces(cell, rel, view)
    except ValueError as e:
        return str(e)
    return None


# -- rendering ------------------------------------------------------------------


def render_cell(cell: Cell, path: pathlib.Path, *, num_threads: int = 1, progress=None) -> None:
    """Simulate and render one cell into ``path`` (atomically: a file that
    exists is complete)."""
    rel, view, bg, cam = scene(cell)
    sim = synth.simulate(
        rel, view, cell.duration_s, cam.frame_rate_hz, seed=cell.seed, num_threads=num_threads
    )
    with atomic_path(path) as tmp:
        render.render_recording(
            sim,
            cam,
            bg,
            tmp,
            seed=cell.seed,
            camera_preset_name=cell.camera,
            num_threads=num_threads,
            progress=progress,
        )


def write_manifest(cells: Sequence[Cell], renders: pathlib.Path, path: pathlib.Path) -> None:
    """The batch manifest (CSV, docs/batch.md): one row per rendering, its
    surfaces and source, defaults otherwise."""
    with atomic_open(path, newline="") as fh:
        w = csv.writer(fh)
        w.writerow(["path", "name", "surfaces", "source", "species"])
        for c in cells:
            lines, src = surfaces(c)
            w.writerow(
                [
                    str((renders / f"{c.name}.h5").resolve()),
                    c.name,
                    ";".join(",".join(f"{v:g}" for v in line) for line in lines),
                    f"{src[0]:g},{src[1]:g}",
                    "CH4",
                ]
            )


# -- evaluation -----------------------------------------------------------------


def scene_snr(truth_kg_h: Optional[float], nec_kg_m2: Optional[float], speed_m_s, width_m) -> float:
    """``Q_true / (NEC v w)`` (NaN when a factor is unknown or not positive).

    Parameters
    ----------
    truth_kg_h : float, kg/h
    nec_kg_m2 : float
        The noise-equivalent column (``SpeciesRate.detection``).
    speed_m_s, width_m : float
        The gas speed normal to the surface (its magnitude is taken) and the
        plume's effective width along it: the true mean plume's
        (:func:`surface_truth`) for ``snr``, the result's detection record for
        ``snr_measured``.
    """
    try:
        nec, v, w = float(nec_kg_m2), abs(float(speed_m_s)), float(width_m)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan
    if truth_kg_h is None or not nec * v * w > 0:
        return math.nan
    return float(truth_kg_h) / 3600.0 / (nec * v * w)


#: The columns of ``cells.csv`` after the cell's axes.
CELL_COLUMNS = [
    "scene",
    "block",
    *AXES,
    "surface",
    "surface_px",
    "status",
    "truth_kg_h",
    "mean_kg_h",
    "ci90_low_kg_h",
    "ci90_high_kg_h",
    "error_pct",
    "covers",
    "covers_budget",
    "expected_error_pct",
    "detected",
    "detection_limit_kg_h",
    "upper_limit_kg_h",
    "snr",
    "snr_measured",
    "warnings",
    "error",
]


def cell_rows(
    cell: Cell, result: Optional[dict], failure: Optional[str] = None, status: str = "failed"
) -> List[dict]:
    """``cells.csv`` rows of one rendering: one per surface from its result
    JSON (``Result.to_dict``), or one row with ``status`` (``failed``, ``not
    done``) and ``failure`` as its error."""
    head = {"scene": cell.scene, "block": cell.block, **cell.axes()}
    if result is None:
        return [{**head, "status": status, "error": failure or "no result"}]
    warnings = result.get("warnings") or []
    try:
        truth_axis = surface_truth(cell)
    except ValueError:  # the mean axis ends before a surface (none was placed there)
        truth_axis = []
    rows = []
    for k, s in enumerate(result["surfaces"]):
        r = s["species"]["CH4"]
        det = r.get("detection") or {}
        speed, width = truth_axis[k] if k < len(truth_axis) else (math.nan, math.nan)
        truth, mean = r.get("truth_kg_h"), r.get("mean_kg_h")
        # A null end is an unbounded one (a NaN interval is a failed result).
        lo, hi = r["ci90_kg_h"]
        lo, hi = (-math.inf if lo is None else lo), (math.inf if hi is None else hi)
        ok = truth is not None and mean is not None
        # The budget's interval before the error model's calibration, and
        # the error the model expects (qogi.pipeline.error_model).
        model = r.get("error_model") or {}
        blo, bhi = model.get("ci90_budget_kg_h") or (lo, hi)
        expected = model.get("expected_error")
        codes = sorted({w["code"] for w in warnings if w.get("surface") in (None, s.get("name"))})
        rows.append(
            {
                **head,
                "surface": s.get("name"),
                "surface_px": cell.surfaces_px[k] if k < len(cell.surfaces_px) else None,
                "status": "ok",
                "truth_kg_h": truth,
                "mean_kg_h": mean,
                "ci90_low_kg_h": lo,
                "ci90_high_kg_h": hi,
                "error_pct": 100.0 * (mean / truth - 1.0) if ok and truth else None,
                "covers": bool(lo <= truth <= hi) if ok else None,
                "covers_budget": bool(blo <= truth <= bhi) if ok else None,
                "expected_error_pct": None if expected is None else 100.0 * expected,
                "detected": r.get("detected"),
                "detection_limit_kg_h": r.get("detection_limit_kg_h"),
                "upper_limit_kg_h": r.get("upper_limit_kg_h"),
                "snr": scene_snr(truth, det.get("noise_equivalent_column_kg_m2"), speed, width),
                "snr_measured": scene_snr(
                    truth,
                    det.get("noise_equivalent_column_kg_m2"),
                    det.get("velocity_m_s"),
                    det.get("width_m"),
                ),
                "warnings": " ".join(codes),
                "error": "",
            }
        )
    return rows


def _frac(values) -> float:
    v = [bool(x) for x in values if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return float(np.mean(v)) if v else math.nan


def _bound_exceeded(row: dict) -> bool:
    """A row that said "not detected, < X" of a truth above X."""
    up, truth = row.get("upper_limit_kg_h"), row.get("truth_kg_h")
    return (
        row.get("detected") is False
        and up is not None
        and truth is not None
        and math.isfinite(float(up))
        and float(truth) > float(up)
    )


def aggregate(rows: Sequence[dict]) -> List[dict]:
    """``envelope.csv``: per scene (cell without its seed), over its seeds and
    surfaces: rows, failures, mean error and its spread (standard deviation
    over the rows) [%], interval coverage, detection fraction, fraction of
    rows carrying a warning, median scene signal-to-noise, and the rows that
    said "not detected, < X" of a truth above X (``bound_exceeded``)."""
    by: Dict[str, List[dict]] = {}
    for r in rows:
        by.setdefault(r["scene"], []).append(r)
    out = []
    for sc, rr in by.items():
        ok = [r for r in rr if r["status"] == "ok"]
        failed = [r for r in rr if r["status"] == "failed"]
        err = np.array([r["error_pct"] for r in ok if r["error_pct"] is not None], float)
        snr = np.array([r["snr"] for r in ok], float)
        out.append(
            {
                "scene": sc,
                "block": rr[0]["block"],
                **{a: rr[0][a] for a in AXES if a != "seed"},
                "seeds": len({r["seed"] for r in rr}),
                "rows": len(rr),
                "failed": len({r["seed"] for r in failed}),
                "not_done": len({r["seed"] for r in rr if r["status"] == "not done"}),
                "mean_error_pct": float(err.mean()) if err.size else math.nan,
                "spread_pct": float(err.std(ddof=1)) if err.size > 1 else math.nan,
                "coverage": _frac(r["covers"] for r in ok),
                "coverage_budget": _frac(r.get("covers_budget") for r in ok),
                "detection_fraction": _frac(r["detected"] for r in ok),
                "bound_exceeded": sum(_bound_exceeded(r) for r in ok),
                "warning_fraction": _frac(bool(r["warnings"]) for r in ok) if ok else math.nan,
                "median_snr": float(np.nanmedian(snr)) if np.isfinite(snr).any() else math.nan,
            }
        )
    return out


def _write_csv(path: pathlib.Path, rows: Sequence[dict], columns: Sequence[str]) -> None:
    with atomic_open(path, newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(columns), extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if v is None else v) for k, v in r.items()})


# -- the run --------------------------------------------------------------------

CELLS_CSV = "cells.csv"
ENVELOPE_CSV = "envelope.csv"
ENVELOPE_MD = "envelope.md"


def run(
    grid: Union[str, os.PathLike, Grid],
    outdir: Union[str, os.PathLike],
    *,
    workers: Optional[int] = None,
    threads: Optional[int] = None,
    resume: bool = False,
    plots: bool = False,
    progress: bool = True,
    log=None,
) -> Tuple[List[dict], List[dict]]:
    """Render, quantify and evaluate a grid; returns (cells rows, envelope rows).

    Parameters
    ----------
    grid : str, path or Grid
        A built-in grid name (:data:`GRIDS`), a TOML file, or a loaded grid.
    outdir : path
        ``renders/<cell>.h5``, ``batch/`` (:func:`qogi.apps.batch.run`'s
        outputs), ``manifest.csv``, ``cells.csv``, ``envelope.csv`` (its
        table also in ``envelope.md``), and with ``plots`` the heat maps ``envelope_*.png``.
    workers, threads : int, optional
        Dask worker processes for the quantification and engine threads per
        task (rendering runs in this process with ``threads`` engine threads).
    resume : bool
        Keep renderings and results already in ``outdir`` (a second run redoes
        nothing done); without it an ``outdir`` holding an envelope is refused.

    Raises
    ------
    UsageError
        A bad grid, an ``outdir`` holding an envelope without ``resume``.
    """
    say = (
        (lambda msg: print(msg, file=log or sys.stderr, flush=True))
        if progress
        else (lambda msg: None)
    )
    g = grid if isinstance(grid, Grid) else load_grid(grid)
    out = pathlib.Path(outdir)
    if out.exists() and not out.is_dir():
        raise UsageError(f"-o {out}: is a file; give a folder")
    if (out / CELLS_CSV).exists() and not resume:
        raise UsageError(
            f"-o {out}: already holds an envelope ({CELLS_CSV}); give --resume to continue "
            "it (renderings and results done are kept) or choose another folder"
        )
    for scene_name, why in excluded_scenes(g):
        say(f"qogi envelope: left out {scene_name}: {why}")
    if not g.cells:
        raise UsageError(f"grid {g.name}: every cell was left out (see above); nothing to run")
    renders = out / "renders"
    renders.mkdir(parents=True, exist_ok=True)
    bdir = out / "batch"
    bdir.mkdir(exist_ok=True)
    todo = [c for c in g.cells if not (renders / f"{c.name}.h5").exists()]
    say(
        f"qogi envelope: {len(g.cells)} renderings ({len(g.excluded)} cells left out), "
        f"{len(g.cells) - len(todo)} already rendered"
    )
    # In chunks: each chunk rendered, then everything rendered so far
    # quantified (batch --resume keeps what is done) and the tables written,
    # so that a long grid has results on disk while it runs.
    size = max(8, 4 * (workers or 1))
    render_failed: Dict[str, str] = {}
    rows: List[dict] = []
    env: List[dict] = []
    for start in range(0, max(len(todo), 1), size):
        chunk = todo[start : start + size]
        bar = ProgressBar("qogi envelope: rendering ", enabled=progress and bool(chunk))
        try:
            for k, c in enumerate(chunk):

                def step(f, m, k=start + k, c=c, bar=bar):
                    return bar((k + f) / len(todo), f"{c.name}: {m}")

                try:
                    render_cell(
                        c, renders / f"{c.name}.h5", num_threads=threads or 1, progress=step
                    )
                except ValueError as e:  # the simulator refused the scene
                    render_failed[c.name] = f"rendering failed: {e}"
                    say(f"\nqogi envelope: {c.name}: rendering failed: {e}")
        finally:
            bar.close()
        rows, env = _quantify_rendered(
            g, out, renders, bdir, render_failed, workers, threads, progress, log
        )
    if plots:
        plot(rows, out)
    say(f"qogi envelope: {len(rows)} rows in {out / CELLS_CSV}, {len(env)} cells in {ENVELOPE_CSV}")
    return rows, env


def _quantify_rendered(g, out, renders, bdir, render_failed, workers, threads, progress, log):
    """Quantify every rendering on disk through qogi batch (--resume: what is
    done is kept) and write ``cells.csv`` and ``envelope.csv``; a cell not
    rendered yet is a ``not done`` row."""
    done = [c for c in g.cells if (renders / f"{c.name}.h5").exists()]
    if done:
        manifest = out / "manifest.csv"
        write_manifest(done, renders, manifest)
        batch.run(
            manifest,
            bdir,
            workers=workers,
            threads=threads,
            resume=True,  # results of this grid's renderings, kept by their settings' hash
            progress=progress,
            log=log,
        )
    rows: List[dict] = []
    for c in g.cells:
        res = bdir / c.name / batch.RESULT_JSON
        fail = bdir / c.name / batch.FAILURE_JSON
        if c.name in render_failed:
            rows += cell_rows(c, None, render_failed[c.name])
        elif not (renders / f"{c.name}.h5").exists():
            rows += cell_rows(c, None, "not rendered yet", status="not done")
        elif res.exists():
            rows += cell_rows(c, json.loads(res.read_text()))
        else:
            why = json.loads(fail.read_text()).get("error") if fail.exists() else None
            rows += cell_rows(c, None, why)
    env = aggregate(rows)
    _write_csv(out / CELLS_CSV, rows, CELL_COLUMNS)
    _write_csv(out / ENVELOPE_CSV, env, list(env[0]) if env else ["scene"])
    with atomic_open(out / ENVELOPE_MD) as fh:
        fh.write(markdown(env) + "\n")
    return rows, env


def _pct(v: float, signed: bool = True) -> str:
    if not math.isfinite(v):
        return "-"
    return f"{v:+.0f} %" if signed else f"{v:.0f} %"


def markdown(env: Sequence[dict]) -> str:
    """``envelope.md``: the per-cell table (:func:`aggregate`) in Markdown,
    one section per block."""
    lines = []
    for block in dict.fromkeys(e["block"] for e in env):
        lines += [
            f"**{block}**",
            "",
            "| rate [kg/h] | distance [m] | contrast [K] | wind [m/s] | background | camera "
            "| record [s] | seeds | mean error | spread | interval covers | detected "
            "| warned | median SNR |",
            "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        ]
        for e in (e for e in env if e["block"] == block):
            undone = f" ({e['failed']} failed)" if e["failed"] else ""
            if e["not_done"]:
                undone += f" ({e['not_done']} not done)"
            lines.append(
                f"| {e['rate_kg_h']:.3g} | {e['distance_m']:g} | {e['contrast_K']:+g} "
                f"| {e['wind_m_s']:g} | {e['background']} | {e['camera']} "
                f"| {e['duration_s']:g} | {e['seeds']}{undone} | {_pct(e['mean_error_pct'])} "
                f"| {_pct(e['spread_pct'], False)} | {_pct(100 * e['coverage'], False)} "
                f"| {_pct(100 * e['detection_fraction'], False)} "
                f"| {_pct(100 * e['warning_fraction'], False)} "
                + (f"| {e['median_snr']:.3g} |" if math.isfinite(e["median_snr"]) else "| - |")
            )
        wrong = [e for e in env if e["block"] == block and e.get("bound_exceeded")]
        lines.append("")
        if wrong:
            lines += [
                '"not detected, < X" said of a truth above X: '
                + ", ".join(f"{e['scene']} ({e['bound_exceeded']} rows)" for e in wrong),
                "",
            ]
    return "\n".join(lines).rstrip("\n")


# -- plots ----------------------------------------------------------------------


def _snr_bin(snr: float) -> Optional[str]:
    if not math.isfinite(snr) or snr <= 0:
        return None
    edges = [0, 1, 3, 10, 30, 100, 1000, math.inf]
    for lo, hi in zip(edges[:-1], edges[1:]):
        if lo <= snr < hi:
            return f"{lo:g}-{hi:g}" if math.isfinite(hi) else f">={lo:g}"
    return None


def _pivot(rows, xkey, ykey, xfmt, yfmt):
    """(x labels, y labels, mean error, coverage, n) over ok rows grouped by two keys."""
    ok = [r for r in rows if r["status"] == "ok" and r["error_pct"] is not None]
    pairs = [(xkey(r), ykey(r)) for r in ok]
    xs = sorted({p[0] for p in pairs if p[0] is not None}, key=xfmt)
    ys = sorted({p[1] for p in pairs if p[1] is not None}, key=yfmt)
    err = np.full((len(ys), len(xs)), np.nan)
    cov = np.full_like(err, np.nan)
    n = np.zeros_like(err, dtype=int)
    for i, y in enumerate(ys):
        for j, x in enumerate(xs):
            sel = [r for r, p in zip(ok, pairs) if p == (x, y)]
            if sel:
                err[i, j] = np.mean([r["error_pct"] for r in sel])
                cov[i, j] = _frac(r["covers"] for r in sel)
                n[i, j] = len(sel)
    return xs, ys, err, cov, n


def _heat(ax, data, xs, ys, n, title, cmap, vmin, vmax, fmt):
    im = ax.imshow(data, origin="lower", cmap=cmap, vmin=vmin, vmax=vmax, aspect="auto")
    ax.set_xticks(range(len(xs)), [str(x) for x in xs], rotation=45, ha="right")
    ax.set_yticks(range(len(ys)), [str(y) for y in ys])
    for i in range(len(ys)):
        for j in range(len(xs)):
            if n[i, j]:
                shade = im.cmap(im.norm(data[i, j]))
                dark = 0.299 * shade[0] + 0.587 * shade[1] + 0.114 * shade[2] < 0.5
                ax.text(
                    j,
                    i,
                    fmt(data[i, j]),
                    ha="center",
                    va="center",
                    fontsize=7,
                    color="white" if dark else "black",
                )
    ax.set_title(title, fontsize=9)
    return im


def plot(rows: Sequence[dict], outdir: Union[str, os.PathLike]) -> List[pathlib.Path]:
    """Heat maps of the mean error and the interval coverage: against rate x
    distance (``envelope_rate_distance.png``) and against the scene's
    signal-to-noise x wind (``envelope_snr_wind.png``); every ok row of a
    pair of values pooled. Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = pathlib.Path(outdir)
    written = []
    panels = [
        (
            "envelope_rate_distance.png",
            lambda r: f"{r['rate_kg_h']:.3g}",
            lambda r: f"{r['distance_m']:g}",
            "release rate [kg/h]",
            "distance [m]",
        ),
        (
            "envelope_snr_wind.png",
            lambda r: _snr_bin(r["snr"]),
            lambda r: f"{r['wind_m_s']:g}",
            "scene signal-to-noise Q / (NEC v w)",
            "wind [m/s]",
        ),
    ]
    for fname, xk, yk, xl, yl in panels:
        xs, ys, err, cov, n = _pivot(
            rows, xk, yk, lambda s: float(re.split("[-=]", s.lstrip(">="))[0] or 0), float
        )
        if not xs or not ys:
            continue
        fig, axes = plt.subplots(1, 2, figsize=(9, 3.4), constrained_layout=True)
        im0 = _heat(
            axes[0],
            np.clip(err, -100, 100),
            xs,
            ys,
            n,
            "mean error [%] (clipped at +-100)",
            "RdBu_r",
            -100,
            100,
            lambda v: f"{v:+.0f}",
        )
        im1 = _heat(
            axes[1],
            cov,
            xs,
            ys,
            n,
            "90 % interval covers the truth [fraction]",
            "viridis",
            0,
            1,
            lambda v: f"{v:.2f}",
        )
        for ax in axes:
            ax.set_xlabel(xl)
            ax.set_ylabel(yl)
        fig.colorbar(im0, ax=axes[0])
        fig.colorbar(im1, ax=axes[1])
        with atomic_path(out / fname) as tmp:
            fig.savefig(tmp, dpi=110)
        plt.close(fig)
        written.append(out / fname)
    return written
