"""Synthetic gas releases with exact ground truth.

A turbulent buoyant plume is simulated as Lagrangian Gaussian puffs carried by
the mean flow of an integral (Morton-Taylor-Turner) buoyant-jet model, with
coherent random displacements and ambient meandering; every truth quantity is
computed from the puffs themselves, so it is exact for the simulated field.
See ``docs/synthetic.md`` for the model, its equations, references and limits.

Geometry (shared with the renderer): world x to the right in the image, z up,
y along the viewing direction away from the camera; the stack exit centre is at
``(release.exit_x_m, 0, release.stack_height_m)``. Pixel coordinates are
(column right, row down) with the origin at the top-left pixel centre.

Units are SI: m, s, K, Pa, kg; rates in kg/s unless a name says otherwise.
Big arrays are float32.

Examples
--------
>>> from qogi import synth
>>> sim = synth.simulate_preset("lab-ch4-5slpm-gf320", duration_s=1.0)  # doctest: +SKIP
>>> maps = sim.truth_maps(0)                                             # doctest: +SKIP
>>> maps["column_kg_m2"]["CH4"].shape                                    # doctest: +SKIP
(240, 320)
"""

from __future__ import annotations

import copy
import json
from importlib import resources
from typing import TYPE_CHECKING, Callable, ClassVar, Iterable, Optional, Sequence, Tuple

import numpy as np

from .. import _engine

__all__ = [
    "Release",
    "View",
    "PlumeModel",
    "Simulation",
    "simulate",
    "mean_flow",
    "known_species",
    "presets",
    "preset",
    "preset_release",
    "preset_view",
    "simulate_preset",
    "horizontal_planes",
    "densify",
    "PUFF_FIELDS",
]

#: Columns of :meth:`Simulation.puffs`.
PUFF_FIELDS = (
    "x_m",
    "y_m",
    "z_m",
    "u_m_s",
    "v_m_s",
    "w_m_s",
    "sigma_m",
    "sigma_rate_m_s",
    "mass_kg",
)


class _Options:
    """The engine's options classes (keyword constructor checked on entry, repr,
    to_dict, equality, pickling) plus :meth:`replace`."""

    if TYPE_CHECKING:  # provided by the engine class each subclass mixes in (not overridden)
        fields: ClassVar[Tuple[str, ...]]

        def to_dict(self) -> dict: ...

    def __init__(self, **kwargs):
        unknown = [k for k in kwargs if k not in self.fields]
        if unknown:  # named after the Python class, not the engine's
            raise TypeError(
                f"{type(self).__name__} has no field {unknown[0]!r}; "
                f"fields: {', '.join(self.fields)}"
            )
        super().__init__(**kwargs)

    def replace(self, **kwargs):
        """A copy with some fields changed."""
        d = self.to_dict()
        d.update(kwargs)
        return type(self)(**d)


class Release(_Options, _engine.SynthRelease):
    """A gas release from a round vertical stack (physical conditions).

    Parameters
    ----------
    rate : float, default 5.0
        Release rate in ``rate_unit``; > 0.
    rate_unit : {"SLPM", "kg/h", "kg/s", "g/h"}, default "SLPM"
        SLPM are standard litres per minute at ``standard_temperature_K`` and
        ``standard_pressure_Pa`` (ideal gas).
    composition : dict of str to float, default {"CH4": 1.0}
        Volume (mole) fractions of the released gas, summing to 1; species from
        :func:`known_species`.
    exit_diameter_m : float, default 0.019
        Inner diameter of the exit, m, in [0.001, 2].
    stack_height_m : float, default 0.0
        Exit height, m (places the exit at z = stack_height_m; no ground is
        modelled).
    exit_x_m : float, default 0.0
        Exit position along x, m.
    exit_temperature_K, ambient_temperature_K : float, default 293.15
        K, in [200, 600].
    pressure_Pa : float, default 101325
        Ambient pressure, Pa, in [1e4, 2e5].
    wind_speed_m_s : float, default 0.0
        Mean horizontal wind, m/s, in [0, 30].
    wind_direction_deg : float, default 0.0
        Direction the wind blows towards, degrees from +x towards +y: 0 = to
        the right across the image, 90 = away from the camera along the line
        of sight.
    turbulence_intensity : float, default 0.0
        Ambient sigma_u / wind speed, in [0, 1].
    draft_m_s : float, default 0.0
        RMS horizontal velocity of room drafts, m/s (adds in quadrature).
    ambient_time_scale_s : float, default 3.0
        Lagrangian integral time of the ambient fluctuations, s.
    release_turbulence : float, default 1.0
        The released gas's own turbulence relative to a fully developed
        turbulent buoyant plume (dimensionless), in [0, 1]: 1 = the
        developed plume's puffs (coherent offsets, axial fluctuations); 0 =
        a quiet column that keeps its mean profile and moves only with the
        ambient air (``turbulence_intensity``, ``draft_m_s``). Below 1 a
        low-Reynolds-number exit also stays laminar longer (no entrainment,
        accelerating under its buoyancy and narrowing): 1 + 14 (1 -
        release_turbulence) exit diameters (``docs/synthetic.md``).
    standard_temperature_K : float, default 293.15
        Standard temperature of SLPM (20 C, as many mass-flow controllers).
    standard_pressure_Pa : float, default 101325
        Standard pressure of SLPM.

    Raises
    ------
    ValueError
        Naming the first bad field and its accepted range.
    """

    def emission_rate_kg_s(self) -> dict:
        """Release rate of each species, kg/s (its mass fraction x the rate)."""
        total = self.mass_rate_kg_s()
        return {s: w * total for s, w in self.species_mass_fractions().items()}


class View(_Options, _engine.SynthView):
    """Camera geometry of a synthetic scene.

    The camera looks along +y; its optical axis meets the plane y = 0 (the
    plume axis) at ``(center_x_m, 0, center_z_m)``, ``distance_m`` from the
    camera. Orthographic rays are parallel to +y with a pixel footprint
    ``distance_m * ifov_rad``; perspective rays start at the camera centre
    ``(center_x_m, -distance_m, center_z_m)`` through a pinhole image plane
    (pixel directions ``((col - cx) ifov, 1, -(row - cy) ifov)``).

    Parameters
    ----------
    width_px, height_px : int, default 320, 256
    ifov_rad : float, default 24 deg / 320
        One pixel's angular size, rad.
    distance_m : float, default 1.5
    projection : {"orthographic", "perspective"}, default "orthographic"
    center_x_m, center_z_m : float, default 0
    """

    @classmethod
    def framing(cls, release: Release, exit_pixel: Sequence[float], **kwargs) -> View:
        """A view whose image shows the stack exit at ``exit_pixel`` (column, row)."""
        v = cls(**kwargs)
        fp = v.distance_m * v.ifov_rad
        cx, cy = 0.5 * (v.width_px - 1), 0.5 * (v.height_px - 1)
        v.center_x_m = release.exit_x_m - (exit_pixel[0] - cx) * fp
        v.center_z_m = release.stack_height_m + (exit_pixel[1] - cy) * fp
        v.check()
        return v


class PlumeModel(_Options, _engine.SynthModelOptions):
    """Settings of the plume model that change its output (defaults are the
    documented model; see ``docs/synthetic.md``).

    Parameters
    ----------
    alpha_jet, alpha_plume : float, default 0.0757, 0.1178
        Top-hat entrainment coefficients of a pure jet and a pure plume
        (sqrt(2) x Fischer et al. 1979's Gaussian 0.0535 and 0.0833).
    beta_crossflow : float, default 0.6
        Crossflow entrainment coefficient (Hoult, Fay & Forney 1969).
    concentration_width_ratio : float, default 1.2
        lambda, concentration / velocity Gaussian width.
    edge_speed_fraction : float, default 0.3
        epsilon of the puff speed profile (gas at the plume edge).
    laminar_length_diameters : float, default -1 (automatic)
    development_length_diameters : float, default 4
    puff_size_fraction : float, default 0.35
    puff_rate_per_s : float, default 0 (automatic)
    axial_turbulence : float, default 0.25
    structure_length : float, default 1
    structure_persistence : float, default 1
    modes_per_band : int, default 12
    column_wave_amplitude : float, default 0.06
        Relative amplitude of the axial speed wave of a quiet laminar column
        (times 1 - ``Release.release_turbulence``, gone where the flow has
        developed), in [0, 0.3]; the wave runs at the puffing frequency
        1.5 / sqrt(D [m]) Hz (within +-10 %, seeded).
    column_wave_phase_speed : float, default 0.6
        Its phase speed as a fraction of the local mass-weighted speed, in
        [0.2, 1]: the gas bunches where it is slow, a pattern travelling
        slower than the gas.
    spin_up_s : float, default -1 (automatic)
    seed : int, default 0
    """


def known_species() -> list:
    """Gas species the simulator has thermodynamic data for."""
    return list(_engine.synth_known_species())


def mean_flow(release: Release, model: Optional[PlumeModel] = None, extent_m: float = 1.0) -> dict:
    """The integral-model mean plume until its axis leaves a box of half-size
    ``extent_m`` around the exit (dict of arrays along the axis).

    Keys include ``s_m`` (arc length), ``x_m``, ``y_m``, ``z_m`` (axis),
    ``radius_m`` and ``velocity_m_s`` (top-hat b and V), ``mass_fraction``
    (top-hat Y), ``temperature_K``, ``density_kg_m3``, ``sigma_c_m`` (mean
    concentration width per axis), ``mass_weighted_speed_m_s`` (W_m) and
    ``centre_partial_density_kg_m3``.
    """
    return dict(_engine.synth_mean_flow(release, model or PlumeModel(), float(extent_m)))


def horizontal_planes(heights_m: Iterable[float]) -> list:
    """Control planes z = h (normal +z) as (point, normal) pairs."""
    return [((0.0, 0.0, float(h)), (0.0, 0.0, 1.0)) for h in heights_m]


class Simulation:
    """A simulated release: puffs at every frame time and exact ground truth.

    Frame n is at ``times_s[n] = n / frame_rate_hz``. Species results are
    dicts keyed by species name (the released gas's composition).
    """

    def __init__(self, engine_sim, release: Release, view: View, model: PlumeModel):
        self._sim = engine_sim
        self.release = release
        self.view = view
        self.model = model

    # -- description -------------------------------------------------------
    @property
    def num_frames(self) -> int:
        return self._sim.num_frames

    @property
    def frame_rate_hz(self) -> float:
        return self._sim.frame_rate_hz

    @property
    def times_s(self) -> np.ndarray:
        """Frame times, s (float64)."""
        return np.arange(self.num_frames) / self.frame_rate_hz

    @property
    def species(self) -> list:
        return list(self._sim.species)

    @property
    def mass_fractions(self) -> dict:
        """Mass fraction of each species in the released gas."""
        return dict(zip(self.species, self._sim.species_mass_fractions))

    @property
    def mole_fractions(self) -> dict:
        """Volume (mole) fraction of each species in the released gas."""
        return dict(zip(self.species, self._sim.species_mole_fractions))

    @property
    def mass_rate_kg_s(self) -> float:
        """Release rate of the whole mixture, kg/s."""
        return self._sim.mass_rate_kg_s

    @property
    def emission_rate_kg_s(self) -> dict:
        """Release rate of each species, kg/s (the truth to recover)."""
        return {s: w * self.mass_rate_kg_s for s, w in self.mass_fractions.items()}

    @property
    def box(self) -> dict:
        """Region outside which puffs no longer affect the view: ``lo``, ``hi``, m."""
        return self._sim.box

    @property
    def stats(self) -> dict:
        return self._sim.stats

    @property
    def puff_rate_per_s(self) -> float:
        return self._sim.puff_rate_per_s

    @property
    def spin_up_s(self) -> float:
        return self._sim.spin_up_s

    def mean_flow(self) -> dict:
        """The integral-model mean flow used (see :func:`mean_flow`)."""
        return dict(self._sim.mean_flow())

    def __repr__(self) -> str:
        return (
            f"Simulation({self.num_frames} frames at {self.frame_rate_hz:g} Hz, "
            f"{self.mass_rate_kg_s * 3600:.4g} kg/h of {self.mole_fractions}, "
            f"{self.view.width_px}x{self.view.height_px} px)"
        )

    # -- per frame ---------------------------------------------------------
    def _frame(self, frame: int) -> int:
        f = int(frame)
        if not 0 <= f < self.num_frames:
            raise IndexError(f"frame must be within [0, {self.num_frames - 1}]; got {frame}")
        return f

    def puffs(self, frame: int) -> np.ndarray:
        """The puffs of a frame, float32 (N, 9) with columns :data:`PUFF_FIELDS`."""
        return self._sim.puffs(self._frame(frame))

    def puff_ids(self, frame: int) -> np.ndarray:
        """Release index of each puff of a frame (uint32, same order as
        :meth:`puffs`); a puff keeps its index from frame to frame."""
        return self._sim.puff_ids(self._frame(frame))

    def truth_maps(self, frame: int, num_threads: int = 0) -> dict:
        """Exact line-of-sight truth of one frame (thesis section 4.3.2).

        Returns
        -------
        dict
            ``column_kg_m2``: {species: (H, W) float32}, integral of the
            species' mass density along each pixel's ray, kg/m2;
            ``flux_x_kg_m_s``, ``flux_z_kg_m_s``: {species: (H, W)}, integral
            of rho_s u dl for the image-plane components (x right, z up;
            image rows run along -z), kg/(m s);
            ``velocity_x_m_s``, ``velocity_z_m_s``: (H, W), mass-weighted
            velocity = flux / column (the same for every species; NaN where
            no gas reaches the ray).
        """
        m = self._sim.truth_maps(self._frame(frame), num_threads)
        w = self.mass_fractions
        out = {
            "column_kg_m2": {s: (m["column_kg_m2"] * np.float32(w[s])) for s in w},
            "flux_x_kg_m_s": {s: (m["flux_x_kg_m_s"] * np.float32(w[s])) for s in w},
            "flux_z_kg_m_s": {s: (m["flux_z_kg_m_s"] * np.float32(w[s])) for s in w},
            "velocity_x_m_s": m["velocity_x_m_s"],
            "velocity_z_m_s": m["velocity_z_m_s"],
        }
        return out

    def column_density(self, frame: int) -> dict:
        """Column density maps {species: (H, W) float32}, kg/m2."""
        return self.truth_maps(frame)["column_kg_m2"]

    def velocity_maps(self, frame: int) -> tuple:
        """Mass-weighted velocity maps (x right, z up), each (H, W) float32, m/s."""
        m = self._sim.truth_maps(self._frame(frame), 0)
        return m["velocity_x_m_s"], m["velocity_z_m_s"]

    def plane_flux(self, planes: Sequence, frames: Optional[Iterable[int]] = None) -> dict:
        """Exact mass flux through control planes at each frame.

        Parameters
        ----------
        planes : sequence of (point, normal)
            Each plane through ``point`` (3 floats, m) with ``normal`` (3
            floats, any length); flux is positive along the normal. See
            :func:`horizontal_planes`.
        frames : iterable of int, optional
            Default: all frames.

        Returns
        -------
        dict
            {species: (T, P) float64}, kg/s, with the total under ``"total"``.
        """
        planes = list(planes)
        if not planes:
            raise ValueError("planes must name at least one (point, normal) pair")
        frames = (
            list(range(self.num_frames)) if frames is None else [self._frame(f) for f in frames]
        )
        pts = [tuple(float(c) for c in p[0]) for p in planes]
        nrm = [tuple(float(c) for c in p[1]) for p in planes]
        total = np.asarray(self._sim.plane_flux(pts, nrm, frames))
        out = {s: total * w for s, w in self.mass_fractions.items()}
        out["total"] = total
        return out

    def default_grid(self) -> dict:
        """The box at the pixel footprint: x0, y0, z0, dx, dy, dz (m), nx, ny, nz."""
        return dict(self._sim.default_grid())

    def fields(
        self, frame: int, grid: Optional[dict] = None, velocity: bool = True, num_threads: int = 0
    ) -> dict:
        """3-D fields of one frame on a regular grid.

        Parameters
        ----------
        grid : dict, optional
            ``x0, y0, z0, dx, dy, dz`` (m) and ``nx, ny, nz``; node (i, j, k) at
            (x0 + i dx, y0 + j dy, z0 + k dz). Default :meth:`default_grid`.
        velocity : bool
            Also compute the gas velocity (three components).

        Returns
        -------
        dict
            Arrays (nz, ny, nx) float32: ``partial_density_kg_m3`` (released
            gas), ``mole_fraction`` {species: X_s}, ``temperature_K``
            (adiabatic mixing), ``velocity_x_m_s``, ``velocity_y_m_s``,
            ``velocity_z_m_s`` (the released gas's mass-weighted velocity; the
            mean wind where there is none); ``grid``; ``over_pure`` (nodes
            denser than the pure released gas, 0 expected).
        """
        d = dict(self._sim.fields(self._frame(frame), grid, bool(velocity), num_threads))
        xr = d.pop("mole_fraction")
        d["mole_fraction"] = {s: xr * np.float32(x) for s, x in self.mole_fractions.items()}
        return d

    def ray_samples(
        self,
        frame: int,
        rows: Optional[tuple] = None,
        cols: Optional[tuple] = None,
        num_threads: int = 0,
    ) -> dict:
        """Samples along the pixel rays of an image rectangle, for a renderer.

        Samples lie on planes of constant depth ``y_m[p]``, p = 0 farthest
        from the camera (increasing p runs from the background towards the
        camera), spaced by ``step_m``; each stands for the path length
        ``path_m`` of its pixel (midpoint rule). Only the gas-bearing stretch
        of each ray is kept: pixel (r, c) of the rectangle owns samples
        ``offset[i]:offset[i+1]`` (i = r * C + c) on planes ``first_plane[r,
        c]``, ``first_plane[r, c] + 1``, ...; outside them the ray sees no
        released gas (ambient temperature, zero mole fraction). ``step_m`` is
        the smallest puff width reaching the rectangle, which integrates every
        Gaussian puff to better than 1e-8 relative; columns built from the
        samples agree with :meth:`truth_maps` to < 0.5 % wherever they exceed
        1e-3 of the image's peak and to < 0.1 % above 1e-2 of it (each puff is
        cut off at 5 widths). See :func:`densify` for a (P, R, C) view.

        Parameters
        ----------
        rows, cols : (begin, end), optional
            Half-open pixel ranges; default the whole image. Ask for bands of
            rows to bound memory.

        Returns
        -------
        dict
            ``y_m`` (P,), ``planes``, ``step_m``, ``path_m`` (R, C) float32,
            ``offset`` (R*C+1,) int64, ``first_plane`` (R, C) int32,
            per-sample float32 arrays ``mole_fraction`` {species: (N,)},
            ``temperature_K`` (N,), ``partial_density_kg_m3`` (N,); ``row0``,
            ``col0``, ``over_pure`` (samples denser than the pure gas, 0
            expected).
        """
        r0, r1 = rows if rows is not None else (0, self.view.height_px)
        c0, c1 = cols if cols is not None else (0, self.view.width_px)
        d = dict(
            self._sim.ray_samples(
                self._frame(frame), int(r0), int(r1), int(c0), int(c1), num_threads
            )
        )
        d["mole_fraction"] = dict(zip(self.species, d["mole_fraction"]))
        d["ambient_temperature_K"] = self.release.ambient_temperature_K
        return d


def densify(samples: dict, values: np.ndarray, fill: float = 0.0) -> np.ndarray:
    """Per-sample ``values`` of :meth:`Simulation.ray_samples` as a dense
    (planes, rows, cols) float32 array, ``fill`` where a ray has no sample
    (use the ambient temperature for ``temperature_K``)."""
    rows, cols = samples["path_m"].shape
    out = np.full((samples["planes"], rows * cols), fill, dtype=np.float32)
    off = samples["offset"]
    first = samples["first_plane"].ravel()
    counts = np.diff(off)
    pix = np.repeat(np.arange(rows * cols), counts)
    plane = np.repeat(first, counts) + (np.arange(off[-1]) - np.repeat(off[:-1], counts))
    out[plane, pix] = values
    return out.reshape(samples["planes"], rows, cols)


def simulate(
    release: Release,
    view: View,
    duration_s: float,
    frame_rate_hz: float,
    seed: int = 0,
    model: Optional[PlumeModel] = None,
    progress: Optional[Callable[[float], Optional[bool]]] = None,
    num_threads: int = 0,
) -> Simulation:
    """Simulate a release and keep every frame's puffs.

    Parameters
    ----------
    release, view : Release, View
    duration_s, frame_rate_hz : float
        ``round(duration_s * frame_rate_hz)`` frames at t = n / frame_rate_hz.
    seed : int
        Overrides ``model.seed``; equal seeds give identical runs on any
        number of threads.
    model : PlumeModel, optional
    progress : callable(fraction) -> bool or None, optional
        Called with the finished fraction; return False to cancel
        (raises KeyboardInterrupt, as does Ctrl-C).
    num_threads : int
        0 = all cores.
    """
    if not isinstance(release, Release) or not isinstance(view, View):
        raise TypeError("release and view must be qogi.synth.Release and qogi.synth.View")
    model = (model or PlumeModel()).replace(seed=int(seed))
    sim = _engine.SynthSimulation(
        release, view, float(duration_s), float(frame_rate_hz), model, int(num_threads), progress
    )
    return Simulation(sim, release, view, model)


# -- presets -----------------------------------------------------------------


def _preset_table() -> dict:
    text = resources.files("qogi").joinpath("data/synth_presets.json").read_text()
    return json.loads(text)["presets"]


def presets() -> list:
    """Names of the built-in presets (thesis scenes)."""
    return list(_preset_table())


def preset(name: str) -> dict:
    """A preset's full description (release, camera, scene, duration, sources,
    assumptions), as a fresh dict."""
    table = _preset_table()
    if name not in table:
        raise ValueError(f"unknown preset {name!r}; presets: {', '.join(table)}")
    return copy.deepcopy(table[name])


def preset_release(name: str) -> Release:
    """The preset's :class:`Release`."""
    return Release(**preset(name)["release"])


def preset_view(name: str, projection: Optional[str] = None) -> View:
    """The preset's :class:`View` (its camera framed on the exit)."""
    p = preset(name)
    cam, scene = p["camera"], p["scene"]
    return View.framing(
        preset_release(name),
        scene["exit_pixel"],
        width_px=cam["width_px"],
        height_px=cam["height_px"],
        ifov_rad=cam["ifov_rad"],
        distance_m=scene["distance_m"],
        projection=projection or scene["projection"],
    )


def simulate_preset(
    name: str,
    duration_s: Optional[float] = None,
    frame_rate_hz: Optional[float] = None,
    seed: int = 0,
    projection: Optional[str] = None,
    model: Optional[PlumeModel] = None,
    progress=None,
    num_threads: int = 0,
) -> Simulation:
    """Simulate a preset (defaults: its duration and camera frame rate)."""
    p = preset(name)
    return simulate(
        preset_release(name),
        preset_view(name, projection),
        p["duration_s"] if duration_s is None else duration_s,
        p["camera"]["frame_rate_hz"] if frame_rate_hz is None else frame_rate_hz,
        seed=seed,
        model=model,
        progress=progress,
        num_threads=num_threads,
    )
