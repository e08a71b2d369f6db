"""The synthetic camera: render a simulated release into a recording with exact truth.

Each pixel's line of sight is marched through the simulated 3-D field
(:meth:`qogi.synth.Simulation.ray_samples`: mole fractions and temperature along
the ray, from the background towards the camera) with the radiative transfer
equation of the forward model (thesis eq. 5), seen through the camera's
channels (eq. 14), in front of a blackbody background, with NETD noise and,
optionally, the emission of warm filters.

How the radiative transfer is made fast enough for 700 frames in minutes
------------------------------------------------------------------------
The fast forward model (spectral binning, :mod:`qogi.physics.forward`) needs thousands
of bins per channel. For one scene, whose gas composition, temperatures and
paths are fixed by the simulation, far fewer suffice: the renderer computes
every bin's contrast on a training set of the scene's own rays (taken from
frames spread over the run and stratified by column), then picks a small
subset of bins and non-negative weights that reproduce the full model's
channel contrast on those rays (selection by non-negative least
squares: Lawson-Hanson NNLS over all bins, which is sparse by itself; the
"optimal spectral sampling" idea of Moncet et al., 2008). Each
selected bin is still solved with the full radiative transfer along the
actual, non-Gaussian path, so saturation, temperature structure and the
zero-contrast limit are physical. The subset's error against the full model
is measured on held-out rays of other frames and stored in the recording
(``/truth`` attrs ``render_contrast_error_max_<channel>``).
"""

from __future__ import annotations

import dataclasses
import logging
import math
import time
from typing import Callable, ClassVar, List, Optional, Sequence, Tuple

import numpy as np

from .. import _engine
from ..hdf5_files import set_attr
from ..io.hdf5_writer import RecordingWriter
from ..io.recording import Scene, Truth
from ..physics import camera as camera_mod
from ..physics.camera import Camera
from ..physics.forward import ForwardModel
from ..physics.optics import SpectralResponse
from ..physics.presets import camera_preset
from ..progress import report
from . import backdrop
from . import plume as synth

log = logging.getLogger(__name__)

__all__ = ["Background", "Jitter", "SceneRenderer", "nnls", "render_recording", "synthesize"]


@dataclasses.dataclass
class Background:
    """The blackbody behind the plume: a per-pixel map of radiometric
    temperature, optionally changing with time (:mod:`qogi.synth.backdrop`).

    The base field by ``kind``:

    * ``"plate"``: uniform at ``temperature_K`` (a lab backdrop);
    * ``"sky"``: rising linearly from ``sky_top_K`` at the top image row to
      ``sky_bottom_K`` at the bottom row (colder overhead than near the
      horizon). The MWIR clear sky is not a blackbody; an effective
      radiometric temperature per pixel is the approximation made here;
    * ``"wall"``: a cladded wall or tank at ``temperature_K`` with seams
      (``-seam_K``, every ``panel_px``) and bolts (``+bolt_K``), and a shadow
      (``-shadow_K``) left of a straight edge through ``shadow_x_fraction``
      of the width at the top row, leaning ``shadow_slope`` px per row;
    * ``"pipe-rack"``: structure at ``temperature_K`` behind horizontal pipes
      and vertical supports, alternately ``+pipe_hot_K`` and ``-pipe_cold_K``,
      with sharp edges.

    Any kind takes a static fine texture (``texture_K`` RMS, correlation
    ``texture_px``) and broken clouds (``cloud_K`` warmer at full cover,
    ``cloud_cover`` of the frame, size ``cloud_px``, drifting at
    ``cloud_drift_px_s`` = (x right, y down) px/s; soft edges). Every random
    element is drawn from ``seed``. Temperatures K, sizes px.
    """

    kind: str = "plate"
    temperature_K: Optional[float] = 288.15
    sky_top_K: float = 240.0
    sky_bottom_K: float = 265.0
    texture_K: float = 0.0
    texture_px: float = 4.0
    cloud_K: float = 0.0
    cloud_cover: float = 0.4
    cloud_px: float = 25.0
    cloud_drift_px_s: Tuple[float, float] = (0.0, 0.0)
    seam_K: float = 0.0
    bolt_K: float = 0.0
    panel_px: float = 48.0
    shadow_K: float = 0.0
    shadow_x_fraction: float = 0.5
    shadow_slope: float = 0.3
    pipe_hot_K: float = 0.0
    pipe_cold_K: float = 0.0
    seed: int = 0

    KINDS: ClassVar[Tuple[str, ...]] = ("plate", "sky", "wall", "pipe-rack")

    def __post_init__(self):
        if self.kind not in self.KINDS:
            raise ValueError(
                f"Background kind must be one of {', '.join(self.KINDS)}; got {self.kind!r}"
            )
        if self.kind != "sky" and (
            self.temperature_K is None or not 150.0 <= self.temperature_K <= 600.0
        ):
            raise ValueError(
                f"a {self.kind} background needs temperature_K within [150, 600] K; "
                f"got {self.temperature_K}"
            )
        for name in ("sky_top_K", "sky_bottom_K"):
            v = getattr(self, name)
            if not (150.0 <= v <= 600.0):
                raise ValueError(f"{name} must be within [150, 600] K; got {v}")
        for name in ("texture_K", "cloud_K", "seam_K", "bolt_K", "shadow_K"):
            v = getattr(self, name)
            if not 0.0 <= v <= 100.0:
                raise ValueError(f"{name} must be within [0, 100] K; got {v}")
        for name in ("pipe_hot_K", "pipe_cold_K"):
            v = getattr(self, name)
            if not 0.0 <= v <= 200.0:
                raise ValueError(f"{name} must be within [0, 200] K; got {v}")
        for name in ("texture_px", "cloud_px", "panel_px"):
            v = getattr(self, name)
            if not 0.5 <= v <= 1000.0:
                raise ValueError(f"{name} must be within [0.5, 1000] px; got {v}")
        if not 0.0 < self.cloud_cover < 1.0:
            raise ValueError(f"cloud_cover must be within (0, 1); got {self.cloud_cover}")
        self.cloud_drift_px_s = tuple(float(v) for v in self.cloud_drift_px_s)  # type: ignore[assignment]
        if len(self.cloud_drift_px_s) != 2 or not all(
            math.isfinite(v) and abs(v) <= 1000.0 for v in self.cloud_drift_px_s
        ):
            raise ValueError(
                f"cloud_drift_px_s must be two speeds (x, y) within +-1000 px/s; "
                f"got {self.cloud_drift_px_s}"
            )
        self._static_cache: dict = {}
        self._clouds: dict = {}

    @classmethod
    def from_dict(cls, d: dict, seed: int = 0) -> Background:
        """From a preset table's ``scene.background`` (keys are the fields;
        ``seed`` is the recording's unless the table gives one)."""
        known = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ValueError(
                f"unknown background field(s) {', '.join(unknown)}; "
                f"fields: {', '.join(sorted(known))}"
            )
        kw = {k: v for k, v in d.items() if v is not None or k == "temperature_K"}
        kw.setdefault("seed", int(seed))
        if "cloud_drift_px_s" in kw:
            kw["cloud_drift_px_s"] = tuple(kw["cloud_drift_px_s"])
        return cls(**kw)

    @property
    def static(self) -> bool:
        """True when the map does not change with time (no drifting clouds)."""
        return self.cloud_K == 0.0 or self.cloud_drift_px_s == (0.0, 0.0)

    @property
    def structured(self) -> bool:
        """True when the map is more than the plate's constant or the sky's
        row gradient."""
        return self.kind in ("wall", "pipe-rack") or self.texture_K > 0 or self.cloud_K > 0

    def _plate_K(self) -> float:
        if self.temperature_K is None:  # __post_init__ refuses a plate without one
            raise ValueError("a plate background needs temperature_K")
        return float(self.temperature_K)

    def row_temperatures(self, height: int) -> np.ndarray:
        """Radiometric temperature of each image row [K] of the base field
        (plate or sky; the row mean of the static map otherwise)."""
        if self.kind == "plate":
            return np.full(height, self._plate_K())
        if self.kind == "sky":
            return np.linspace(self.sky_top_K, self.sky_bottom_K, height)
        return np.full(height, self._plate_K())

    def _static_map(self, height: int, width: int) -> np.ndarray:
        key = (int(height), int(width))
        if key not in self._static_cache:
            m = np.repeat(self.row_temperatures(height)[:, None], width, axis=1)
            if self.kind == "wall":
                m += backdrop.wall_features(
                    height, width, self.seam_K, self.bolt_K, self.panel_px, self.seed
                )
                if self.shadow_K > 0:
                    m += backdrop.shadow_edge(
                        height,
                        width,
                        self.shadow_K,
                        self.shadow_x_fraction * (width - 1),
                        self.shadow_slope,
                    )
            elif self.kind == "pipe-rack":
                m += backdrop.pipe_rack(height, width, self.pipe_hot_K, self.pipe_cold_K, self.seed)
            if self.texture_K > 0:
                m += backdrop.texture_field(
                    height, width, self.texture_K, self.texture_px, self.seed
                )
            self._static_cache[key] = m
        return self._static_cache[key]

    def temperature_map(self, height: int, width: int, time_s: float = 0.0) -> np.ndarray:
        """Radiometric temperature of every pixel at ``time_s`` [K], (H, W)
        float64 (a fresh array)."""
        m = self._static_map(height, width).copy()
        if self.cloud_K > 0:
            key = (int(height), int(width))
            if key not in self._clouds:
                self._clouds[key] = backdrop.CloudField(
                    height,
                    width,
                    self.cloud_K,
                    self.cloud_cover,
                    self.cloud_px,
                    self.cloud_drift_px_s,
                    self.seed,
                )
            m += self._clouds[key].temperature(float(time_s))
        return m

    def temperature_range(self, height: int, width: int) -> Tuple[float, float]:
        """The coldest and warmest the map can be [K] (clouds at full cover
        anywhere)."""
        m = self._static_map(height, width)
        return float(m.min()), float(m.max()) + self.cloud_K

    def representative_K(self) -> float:
        if self.kind == "sky":
            return 0.5 * (self.sky_top_K + self.sky_bottom_K)
        return self._plate_K()


@dataclasses.dataclass(frozen=True)
class Jitter:
    """A vibrating tripod: the whole image moves rigidly, frame by frame.

    The motion is a sum of eight sinusoids per component with frequencies
    drawn uniformly within ``frequency_hz`` x [0.5, 1.5] and random phases
    (seeded), scaled so that the displacement's root-mean-square over the
    run is ``rms_px`` (x and y alike) and the rotation's ``rotation_rms_rad``
    (about the image centre). The renderer draws each frame ``margin_px``
    larger on every side and resamples it by this motion
    (:func:`qogi._engine.warp_to_reference`, bicubic) before cutting the
    camera's image out of it, so no border is invented; background and gas
    move together and the sensor's noise is added after, as in a real camera.

    Parameters
    ----------
    rms_px : float, default 0.3
        Displacement rms [px], in [0, 3].
    frequency_hz : float, default 2.0
        Typical vibration frequency [Hz], > 0.
    rotation_rms_rad : float, default 0.0
        Rotation rms [rad], in [0, 0.01].
    seed : int, default 0
    """

    rms_px: float = 0.3
    frequency_hz: float = 2.0
    rotation_rms_rad: float = 0.0
    seed: int = 0

    def __post_init__(self):
        if not 0.0 <= self.rms_px <= 3.0:
            raise ValueError(f"Jitter rms_px must be within [0, 3] px; got {self.rms_px}")
        if not self.frequency_hz > 0.0:
            raise ValueError(f"Jitter frequency_hz must be > 0 Hz; got {self.frequency_hz}")
        if not 0.0 <= self.rotation_rms_rad <= 0.01:
            raise ValueError(
                f"Jitter rotation_rms_rad must be within [0, 0.01] rad; got {self.rotation_rms_rad}"
            )

    def margin_px(self, width: int, height: int) -> int:
        """Pixels drawn beyond each image edge: the largest displacement the
        motion can reach (four times its rms, the rotation at the corner) and
        the resampling's reach."""
        corner = 0.5 * float(np.hypot(width, height))
        return int(math.ceil(4.0 * (self.rms_px + self.rotation_rms_rad * corner))) + 3

    def motion(self, times_s) -> np.ndarray:
        """The rigid motion at each time, (T, 3): dx, dy [px] (the frame's
        content at W(x) = R(angle)(x - c) + c + (dx, dy) is the still
        camera's at x) and angle [rad]."""
        t = np.asarray(times_s, dtype=float)
        rng = np.random.default_rng([int(self.seed), 0x717])
        out = np.zeros((len(t), 3))
        for k, rms in enumerate(
            (self.rms_px / np.sqrt(2), self.rms_px / np.sqrt(2), self.rotation_rms_rad)
        ):
            f = self.frequency_hz * rng.uniform(0.5, 1.5, 8)
            ph = rng.uniform(0, 2 * np.pi, 8)
            x = np.sin(2 * np.pi * f[None, :] * t[:, None] + ph[None, :]).sum(axis=1)
            x -= x.mean()
            r = float(np.sqrt(np.mean(x**2))) if len(t) > 1 else 0.0
            out[:, k] = x * (rms / r) if r > 0 else 0.0
        return out


def _jittered(frame: np.ndarray, motion: np.ndarray, margin: int) -> np.ndarray:
    """The camera's image (C, H, W) cut from a frame drawn ``margin`` px
    larger on every side, moved by ``motion`` (dx, dy, angle)."""
    dx, dy, a = (float(v) for v in motion)
    # Resampling by the inverse motion puts the still scene's x at W(x).
    c, s = math.cos(a), math.sin(a)
    inv = (-(c * dx + s * dy), -(-s * dx + c * dy), -a)
    big = _engine.warp_to_reference(np.ascontiguousarray(frame, np.float32), *inv)
    return big[:, margin:-margin, margin:-margin]


def _lsq(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Least squares on few columns through the small normal equations (the
    columns are few, so this is cheap; a tall QR per NNLS step is not)."""
    g = a.T @ a
    try:
        return np.linalg.solve(g + 1e-14 * np.trace(g) * np.eye(len(g)), a.T @ b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(a, b, rcond=None)[0]


def nnls(a: np.ndarray, b: np.ndarray, max_iter: int = 500) -> np.ndarray:
    """Non-negative least squares, min ||a x - b|| with x >= 0 (Lawson & Hanson
    1974, chapter 23)."""
    m, n = a.shape
    x = np.zeros(n)
    passive = np.zeros(n, dtype=bool)
    w = a.T @ (b - a @ x)
    tol = 10 * np.finfo(float).eps * np.linalg.norm(a, 1) * max(m, n)
    for _ in range(max_iter):
        if passive.all() or np.max(np.where(passive, -np.inf, w)) <= tol:
            break
        j = int(np.argmax(np.where(passive, -np.inf, w)))
        passive[j] = True
        while True:
            idx = np.flatnonzero(passive)
            z = np.zeros(n)
            z[idx] = _lsq(a[:, idx], b)
            if np.all(z[idx] > 0):
                x = z
                break
            neg = idx[z[idx] <= 0]
            alpha = np.min(x[neg] / (x[neg] - z[neg]))
            x = x + alpha * (z - x)
            passive &= x > tol
            x[~passive] = 0.0
        w = a.T @ (b - a @ x)
    return x


def _paths_from_samples(samples: dict, species: Sequence[str], t_amb: float, pixels: np.ndarray):
    """Yield (position, temperature, fractions) paths for the given pixel
    indices of a ray_samples dict, built exactly as the engine renderer does
    (an ambient node beyond each end, padded to an odd node count)."""
    off = samples["offset"]
    path_m = samples["path_m"].ravel()
    temp = samples["temperature_K"]
    fr = [samples["mole_fraction"][s] for s in species]
    for i in pixels:
        s0, s1 = int(off[i]), int(off[i + 1])
        n = s1 - s0 + 2
        if n % 2 == 0:
            n += 1
        pos = np.arange(n) * float(path_m[i])
        t = np.full(n, t_amb)
        t[1 : 1 + s1 - s0] = temp[s0:s1]
        x = np.zeros((n, len(species)))
        for k, f in enumerate(fr):
            x[1 : 1 + s1 - s0, k] = np.clip(f[s0:s1], 0.0, 1.0)
        yield pos, t, x


class SceneRenderer:
    """Renders frames of a simulated release through a camera.

    Parameters
    ----------
    simulation : qogi.synth.Simulation
    camera : qogi.Camera
        Channels, NETD, resolution and IFOV (they must match the simulation's
        view: the same resolution and pixel angle).
    background : Background
    max_bins : int, default 48
        Bins kept per channel for this scene (see the module docstring).
    training_rays : int, default 3000
    warm_filter_temperature_K : float, optional
        Add the emission of the camera's (uncooled) filters and lens at this
        temperature (thesis section 4.3.3). Needs a preset with known optics.
    camera_preset_name : str, optional
        The preset whose optics to use for warm filters.
    line_shape : LineShape or str, optional
        The cross-sections' line shape (default ``fixed:25+self``).
    progress : callable(fraction, message), optional
    """

    def __init__(
        self,
        simulation,
        camera,
        background: Background,
        *,
        max_bins: int = 48,
        training_rays: int = 3000,
        warm_filter_temperature_K: Optional[float] = None,
        camera_preset_name: Optional[str] = None,
        progress: Optional[Callable[[float, str], Optional[bool]]] = None,
        num_threads: int = 0,
        line_shape=None,
    ):
        self.sim = simulation
        self.camera = camera
        self.background = background
        self.num_threads = num_threads
        self._progress = progress
        view = simulation.view
        if camera.width is not None and (view.width_px, view.height_px) != (
            camera.width,
            camera.height,
        ):
            raise ValueError(
                f"the simulation's view is {view.width_px}x{view.height_px} px but the "
                f"camera has {camera.width}x{camera.height}"
            )
        if not math.isclose(view.ifov_rad, camera.ifov_rad, rel_tol=1e-6):
            raise ValueError(
                f"the simulation's view has ifov {view.ifov_rad} rad but the camera "
                f"{camera.ifov_rad} rad; build the view from the camera"
            )
        rel = simulation.release
        self.species = list(simulation.species)
        self.t_amb = float(rel.ambient_temperature_K)
        self.pressure = float(rel.pressure_Pa)
        self.times_s = np.asarray(simulation.times_s, dtype=float)
        # A static background's map and band radiance, made once.
        self._bg_t_static: Optional[np.ndarray] = None
        self._bg_radiance: Optional[np.ndarray] = None
        t_gas = [self.t_amb, float(rel.exit_temperature_K)]
        t_all = t_gas + list(background.temperature_range(view.height_px, view.width_px))
        self.t_range = (max(200.0, min(t_all) - 2.0), min(600.0, max(t_all) + 2.0))
        keys = sorted({round(t, 1) for t in t_gas})
        self._say(0.0, "cross-section tables")
        self.forward = ForwardModel(
            camera.channels, self.species, pressure_Pa=self.pressure, line_shape=line_shape
        )
        opts = _engine.BinnedModelOptions(key_temperatures_K=keys)
        self.full = _engine.BinnedModel(self.forward.channels, self.forward.tables, opts)
        self.optics: Optional[list] = None
        self.warm_filter_temperature_K = warm_filter_temperature_K
        if warm_filter_temperature_K is not None:
            if camera_preset_name is None:
                raise ValueError(
                    "warm filters need the camera preset's optics: give camera_preset_name"
                )
            optics = camera_mod.camera_optics(camera_preset_name)
            # Interference filters block mostly by reflection: out of band,
            # take 95 % of what they do not transmit as reflected (emissivity
            # 5 % of (1 - tau)); the preset's curves are approximations anyway.
            self.optics = [
                camera_mod.ChannelOptics(
                    o.nu_cm1,
                    o.detector_response,
                    o.filter_transmittance,
                    o.lens_transmittance,
                    filter_reflectance=0.95 * (1.0 - np.asarray(o.filter_transmittance)),
                    name=o.name,
                )
                for o in optics
            ]
        self._select_bins(max_bins, training_rays)

    # ------------------------------------------------------------------
    def _say(self, fraction: float, message: str) -> None:

        report(self._progress, fraction, message)  # qogi.Cancelled when told to stop

    def _training_pixels(self, frames: Sequence[int], n_rays: int, rng) -> List[tuple]:
        """(frame, samples, pixel indices) stratified by column over the frames."""
        per_frame = max(1, n_rays // len(frames))
        out = []
        for f in frames:
            s = self.sim.ray_samples(int(f), num_threads=self.num_threads)
            counts = np.diff(s["offset"])
            gas = np.flatnonzero(counts > 0)
            if gas.size == 0:
                continue
            # Column proxy: sum of mole fractions x path length.
            tot = np.zeros(len(s["temperature_K"]))
            for sp in self.species:
                tot += s["mole_fraction"][sp]
            csum = np.concatenate([[0.0], np.cumsum(tot)])
            col = (csum[s["offset"][gas + 1]] - csum[s["offset"][gas]]) * s["path_m"].ravel()[gas]
            keep = gas[col > 0]
            col = col[col > 0]
            if keep.size == 0:
                continue
            # Stratify by log column: equal numbers per decade-ish bin.
            edges = np.quantile(np.log(col), np.linspace(0, 1, 9))
            which = np.clip(np.searchsorted(edges, np.log(col), side="right") - 1, 0, 7)
            chosen = []
            for b in range(8):
                idx = keep[which == b]
                if idx.size:
                    chosen.extend(
                        rng.choice(idx, size=min(idx.size, per_frame // 8 + 1), replace=False)
                    )
            out.append((int(f), s, np.array(chosen, dtype=np.int64)))
        return out

    def _bin_matrix(self, sets: List[tuple], channel: int) -> tuple:
        rows, y = [], []
        w = self.full.weights(channel)
        for f, s, pix in sets:
            ncols = s["path_m"].shape[1]
            r = s["row0"] + pix // ncols
            c = s["col0"] + pix % ncols
            t_bg = self.background_temperature(f)[r, c]
            paths = _paths_from_samples(s, self.species, self.t_amb, pix)
            for (pos, t, x), tb in zip(paths, t_bg):
                a = self.full.bin_contrasts(pos, t, x, self.pressure, channel, float(tb))
                rows.append(a)
                y.append(float(a @ w))
        return np.asarray(rows), np.asarray(y)

    def _select_bins(self, max_bins: int, n_rays: int) -> None:
        rng = np.random.default_rng(12345)
        nf = self.sim.num_frames  # frames start after the simulator's spin-up
        frames = np.unique(np.linspace(0, nf - 1, 8).round().astype(int))
        train_frames, test_frames = frames[::2], frames[1::2]
        if len(test_frames) == 0:
            test_frames = train_frames
        self._say(0.02, "choosing the scene's spectral bins")
        train = self._training_pixels(train_frames, n_rays, rng)
        test = self._training_pixels(test_frames, max(200, n_rays // 3), rng)
        nc = len(self.forward.channels)
        keep, weights, self.render_error = [], [], {}
        for c in range(nc):
            self._say(0.05 + 0.1 * c / nc, f"bins of channel {c}")
            a, y = self._bin_matrix(train, c)
            at, yt = self._bin_matrix(test, c)
            if a.size == 0 or not np.any(y):
                # No gas in view, or gas exactly at the background's temperature
                # (zero contrast on every ray, whatever the bins): keep the
                # best-weighted bins with their own weights.
                w_full = self.full.weights(c)
                top = [int(q) for q in np.argsort(-w_full)[:max_bins]]
                keep.append(top)
                weights.append([float(w_full[q]) for q in top])
                self.render_error[self.forward.channels[c].name] = (0.0, 0.0)
                continue
            floor = 1e-3 * np.max(np.abs(y))
            s = 1.0 / np.maximum(np.abs(y), floor)
            As = a * s[:, None]
            ys = y * s
            # Lawson-Hanson NNLS over all bins picks a sparse set by itself
            # (it adds the bin with the largest positive gradient each step).
            w_all = nnls(As, ys)
            chosen = list(np.flatnonzero(w_all > 0))
            if len(chosen) > max_bins:
                contrib = w_all[chosen] * np.linalg.norm(As[:, chosen], axis=0)
                chosen = [chosen[i] for i in np.argsort(-contrib)[:max_bins]]
            wsel = nnls(As[:, chosen], ys) if chosen else np.zeros(0)
            nz = wsel > 0
            chosen = [int(q) for q, k in zip(chosen, nz) if k]
            wsel = wsel[nz]
            keep.append(chosen)
            weights.append(list(wsel))
            st = 1.0 / np.maximum(np.abs(yt), 1e-3 * np.max(np.abs(yt)))
            err = np.abs(at[:, chosen] @ wsel - yt) * st
            name = self.forward.channels[c].name
            self.render_error[name] = (float(np.max(err)), float(np.sqrt(np.mean(err**2))))
            log.info(
                "channel %s: %d bins, held-out contrast error max %.3g rms %.3g",
                name,
                len(chosen),
                *self.render_error[name],
            )
        self.model = self.full.subset(keep, weights)
        # 0.05 K steps: linear interpolation of Planck and cross-sections errs
        # by < 1e-6 relative, far below the bin selection's error.
        self.model.use_fine_temperature_grid(self.t_range[0], self.t_range[1], 0.05)
        self.bins_per_channel = [len(k) for k in keep]

    # ------------------------------------------------------------------
    def background_temperature(self, frame: int) -> np.ndarray:
        """Radiometric temperature of the bare background at a frame, (H, W) [K]."""
        view = self.sim.view
        if self.background.static:
            if self._bg_t_static is None:
                self._bg_t_static = self.background.temperature_map(view.height_px, view.width_px)
            return self._bg_t_static
        return self.background.temperature_map(
            view.height_px, view.width_px, float(self.times_s[int(frame)])
        )

    def background_radiance(self, frame: int = 0) -> np.ndarray:
        """Band radiance of the bare background at a frame, (C, H, W) [W/(m2 sr)]."""
        if self.background.static and self._bg_radiance is not None:
            return self._bg_radiance
        t = self.background_temperature(frame)
        if self.background.structured:
            # A map of many temperatures: each channel's band radiance on a
            # 0.01 K grid, interpolated (linear interpolation of Planck's law
            # errs by < 1e-8 relative at that step).
            lo, hi = float(t.min()), float(t.max())
            grid = np.arange(lo - 0.02, hi + 0.03, 0.01)
            out = np.stack(
                [np.interp(t, grid, ch.band_radiance(grid)) for ch in self.forward.channels]
            )
        else:  # plate or sky: the exact band radiance of each row
            rows = np.stack([ch.band_radiance(t[:, 0]) for ch in self.forward.channels])
            out = np.repeat(rows[:, :, None], t.shape[1], axis=2)
        if self.background.static:
            self._bg_radiance = out
        return out

    def render_frame(self, frame: int, band_rows: int = 32) -> np.ndarray:
        """Noise-free band radiance of one frame, (C, H, W) float32 [W/(m2 sr)]."""
        view = self.sim.view
        h, w = view.height_px, view.width_px
        nc = len(self.forward.channels)
        out = np.empty((nc, h, w), dtype=np.float32)
        out[:] = self.background_radiance(frame)
        t_bg = self.background_temperature(frame)
        for r0 in range(0, h, band_rows):
            r1 = min(h, r0 + band_rows)
            s = self.sim.ray_samples(int(frame), rows=(r0, r1), num_threads=self.num_threads)
            if s["offset"][-1] == 0:
                continue
            tb = np.ascontiguousarray(
                np.repeat(t_bg[r0:r1].reshape(-1, 1), nc, axis=1), dtype=float
            ).ravel()
            fr = [
                np.ascontiguousarray(np.clip(s["mole_fraction"][sp], 0.0, 1.0), dtype=np.float32)
                for sp in self.species
            ]
            c = _engine.render_contrast(
                self.model,
                s["offset"],
                s["path_m"].ravel(),
                s["temperature_K"],
                fr,
                self.t_amb,
                tb,
                num_threads=self.num_threads,
            )
            out[:, r0:r1, :] += c.reshape(r1 - r0, w, nc).transpose(2, 0, 1)
        return out


def _camera_for(preset: dict):

    name = preset["camera"]["name"]
    key = "gf320" if "GF320" in name.upper() else name
    return key, camera_preset(key)


def render_recording(
    sim,
    camera,
    background: Background,
    path,
    *,
    seed: int = 0,
    noise: bool = True,
    warm_filter_temperature_K: Optional[float] = None,
    camera_preset_name: Optional[str] = None,
    truth_maps: bool = False,
    truth_plane_heights_m: Optional[Sequence[float]] = None,
    compression: Optional[str] = "lzf",
    progress=None,
    num_threads: int = 0,
    max_bins: int = 48,
    line_shape=None,
    jitter: Optional[Jitter] = None,
    filter_wheel: bool = False,
):
    """Render a simulation into a recording file (docs/recording.md contract) with ``/truth``.

    ``/truth`` holds ``emission_rate_kg_s_<SPECIES>`` and datasets
    ``plane_height_m`` (P,), ``plane_row`` (P,) (image row of each horizontal
    plane), ``plane_flux_kg_s_<SPECIES>`` (T, P) (the exact mass flux through each
    plane per frame), and with ``truth_maps=True`` per-frame
    ``column_density_kg_m2_<SPECIES>`` (T, H, W) and ``velocity_m_s`` (T, 2, H, W)
    (mass-weighted x right and z up components). Attrs record the renderer's
    measured error against the full fast model.

    ``jitter`` (:class:`Jitter`) moves every frame rigidly: the simulation's
    view must then be ``jitter.margin_px(camera.width, camera.height)``
    larger than the camera on every side (:func:`synthesize` makes it so);
    the motion applied is kept in ``/truth`` datasets ``jitter_dx_px``,
    ``jitter_dy_px``, ``jitter_angle_rad`` (T,) and the truth maps are in the
    still camera's geometry. ``filter_wheel=True`` renders channel k of frame
    i at simulation frame ``C i + k`` (C channels): the simulation runs at C
    times the camera's frame rate and each channel is seen at its own time
    within a wheel turn, as the FAST M150's filter wheel does; the frame's
    time is its turn's mean, the channels' offsets from it are the root
    attribute ``channel_time_offset_s`` (as ``qogi convert`` writes for a
    Telops file), the plane fluxes are the turn's means and the truth maps
    those of simulation frame ``C i + C // 2``.
    """

    t0 = time.perf_counter()

    def say(f, msg):

        report(progress, f, msg)  # qogi.Cancelled when told to stop

    view = sim.view
    margin = 0
    if jitter is not None:
        if camera.width is None or camera.height is None:
            raise ValueError("jitter needs the camera's width and height")
        margin = jitter.margin_px(camera.width, camera.height)
        if (view.width_px, view.height_px) != (
            camera.width + 2 * margin,
            camera.height + 2 * margin,
        ):
            raise ValueError(
                f"with jitter the simulation's view must be {margin} px larger than the "
                f"camera ({camera.width}x{camera.height}) on every side; got "
                f"{view.width_px}x{view.height_px} (render with qogi.synth.render.synthesize)"
            )
    renderer = SceneRenderer(
        sim,
        dataclasses.replace(camera, width=view.width_px, height=view.height_px),
        background,
        progress=lambda f, m: say(0.1 * f, m),
        warm_filter_temperature_K=warm_filter_temperature_K,
        camera_preset_name=camera_preset_name,
        num_threads=num_threads,
        max_bins=max_bins,
        line_shape=line_shape,
    )
    rel = sim.release
    nc = len(renderer.forward.channels)
    turn = nc if filter_wheel else 1  # simulation frames per recorded frame
    out_h, out_w = view.height_px - 2 * margin, view.width_px - 2 * margin
    scene = Scene(
        distance_m=float(view.distance_m),
        ambient_temperature_K=float(rel.ambient_temperature_K),
        pressure_Pa=float(rel.pressure_Pa),
        wind_speed_m_s=float(rel.wind_speed_m_s),
        gas_temperature_K=float(rel.exit_temperature_K),
        background_temperature_K=background.representative_K(),
        species=tuple(renderer.species),
    )
    cam = Camera(
        name=camera.name,
        ifov_rad=float(camera.ifov_rad),
        channels=[
            SpectralResponse(c.nu_cm1, c.response, c.name) for c in renderer.forward.channels
        ],
        frame_rate_hz=float(sim.frame_rate_hz) / turn,
        netd_K=camera.netd_K,
        width=out_w,
        height=out_h,
    )
    # Truth planes: horizontal planes at heights above the exit (world z), and their image rows.
    exit_z = float(rel.stack_height_m)
    if truth_plane_heights_m is None:
        span = view.height_px * view.ifov_rad * view.distance_m
        truth_plane_heights_m = [
            h
            for h in (0.02, 0.04, 0.06, 0.08, 0.10, 0.12, 0.2, 0.3, 0.5, 1.0, 2.0)
            if h < 0.9 * span
        ]
    heights = np.asarray(truth_plane_heights_m, dtype=float)
    pix = view.ifov_rad * view.distance_m
    cy = (out_h - 1) / 2.0
    rows = cy - (exit_z + heights - view.center_z_m) / pix
    planes = synth.horizontal_planes(list(exit_z + heights))
    nf = sim.num_frames // turn
    flux = {
        sp: np.asarray(v[: nf * turn]).reshape(nf, turn, -1).mean(axis=1)
        for sp, v in sim.plane_flux(planes).items()
    }
    truth = Truth(
        emission_rate_kg_s=dict(sim.emission_rate_kg_s),
        datasets={
            "plane_height_m": heights,
            "plane_row": rows.astype(np.float64),
            **{
                f"plane_flux_kg_s_{sp}": np.asarray(flux[sp], dtype=np.float64)
                for sp in renderer.species
            },
        },
        attrs={
            "generator": "qogi.synth.render",
            "seed": int(seed),
            "line_shape": str(renderer.forward.line_shape),
            "render_bins_per_channel": list(renderer.bins_per_channel),
            **{f"render_contrast_error_max_{k}": v[0] for k, v in renderer.render_error.items()},
            **{f"render_contrast_error_rms_{k}": v[1] for k, v in renderer.render_error.items()},
            "noise": bool(noise),
            "warm_filter_temperature_K": (
                -1.0 if warm_filter_temperature_K is None else float(warm_filter_temperature_K)
            ),
            "spin_up_s": float(sim.spin_up_s),
        },
    )
    h, w = out_h, out_w
    tbg_per_channel = [float(background.representative_K())] * nc
    sub_times = np.asarray(sim.times_s, dtype=float)
    times = sub_times[: nf * turn].reshape(nf, turn).mean(axis=1)
    motion = jitter.motion(sub_times) if jitter is not None else None
    if jitter is not None and motion is not None:
        truth.datasets.update(
            jitter_dx_px=motion[:, 0].copy(),
            jitter_dy_px=motion[:, 1].copy(),
            jitter_angle_rad=motion[:, 2].copy(),
        )
        truth.attrs.update(jitter_rms_px=jitter.rms_px, jitter_frequency_hz=jitter.frequency_hz)
        if filter_wheel:  # each channel's own motion: (T, C) per component
            for k, name in enumerate(("jitter_dx_px", "jitter_dy_px", "jitter_angle_rad")):
                truth.datasets[name] = motion[: nf * turn, k].reshape(nf, turn).copy()

    def drawn(f: int) -> np.ndarray:
        """Sub-frame f, noise-free, in the camera's image (moved when jittered)."""
        big = renderer.render_frame(f)
        return big if motion is None else _jittered(big, motion[f], margin)

    with RecordingWriter(
        path,
        quantity="radiance",
        camera=cam,
        scene=scene,
        frame_shape=(nc, h, w),
        truth=truth,
        compression=compression,
        expected_frames=nf,
    ) as writer:
        if filter_wheel:
            offsets = (np.arange(turn) - (turn - 1) / 2.0) / float(sim.frame_rate_hz)
            set_attr(writer.truth_group.file, "channel_time_offset_s", offsets)
        for f in range(nf):
            if filter_wheel:
                frame = np.stack([drawn(turn * f + k)[k] for k in range(nc)])
            else:
                frame = drawn(f)
            if renderer.optics is not None and warm_filter_temperature_K is not None:
                t_f = float(warm_filter_temperature_K)
                frame = camera_mod.add_warm_optics(frame, renderer.optics, t_f, t_f)
            if noise:
                frame = camera_mod.add_netd_noise(
                    frame,
                    renderer.forward.channels,
                    camera.netd_K,
                    tbg_per_channel,
                    seed=seed,
                    offset=f * frame.size,
                )
            writer.append(frame[None].astype(np.float32), times[f : f + 1])
            say(0.1 + 0.85 * (f + 1) / nf, f"frame {f + 1}/{nf}")
        if truth_maps:
            g = writer.truth_group
            cols = {
                sp: g.create_dataset(
                    f"column_density_kg_m2_{sp}",
                    (nf, h, w),
                    np.float32,
                    chunks=(1, h, w),
                    compression="lzf",
                )
                for sp in renderer.species
            }
            vel = g.create_dataset(
                "velocity_m_s", (nf, 2, h, w), np.float32, chunks=(1, 2, h, w), compression="lzf"
            )
            set_attr(vel, "components", "x right, z up (mass-weighted along each line of sight)")
            inner = (slice(margin, margin + h), slice(margin, margin + w))
            for f in range(nf):
                m = sim.truth_maps(turn * f + turn // 2)
                for sp in renderer.species:
                    cols[sp][f] = m["column_kg_m2"][sp][inner]
                vel[f, 0] = m["velocity_x_m_s"][inner]
                vel[f, 1] = m["velocity_z_m_s"][inner]
                say(0.95 + 0.05 * (f + 1) / nf, f"truth maps {f + 1}/{nf}")
    log.info("rendered %d frames in %.1f s", nf, time.perf_counter() - t0)
    return path


def synthesize(
    preset_name: str,
    path,
    *,
    duration_s: Optional[float] = None,
    frame_rate_hz: Optional[float] = None,
    seed: int = 0,
    noise: bool = True,
    truth_maps: bool = False,
    camera_name: Optional[str] = None,
    progress=None,
    num_threads: int = 0,
    line_shape=None,
    jitter: Optional[Jitter] = None,
    filter_wheel: bool = False,
):
    """Simulate and render a preset (``qogi synth``). Returns the path written.

    ``camera_name`` renders the release through another camera preset (e.g.
    the four-channel ``fast-m150`` for a GF320 lab release), placed so that its
    pixels have the preset's footprint at the plume and the exit sits at the
    same place relative to the image's bottom edge; the frame rate defaults to
    that camera's. ``line_shape`` (:class:`qogi.physics.forward.LineShape` or its
    text, default ``fixed:25+self``) is the renderer's line shape (recorded
    in the truth's ``line_shape`` attribute). ``jitter`` (:class:`Jitter`)
    shakes the camera; ``filter_wheel=True`` sees each channel at its own
    time within a wheel turn (see :func:`render_recording`)."""

    p = synth.preset(preset_name)
    cam_key, camera = _camera_for(p)
    view = None
    if jitter is not None or filter_wheel:
        camera_name = camera_name or cam_key
    if camera_name is not None and (camera_name != cam_key or jitter is not None):
        # Another camera at the same pixel footprint, framed on the same exit.

        base = synth.preset_view(preset_name)
        footprint = base.distance_m * base.ifov_rad
        camera = camera_preset(camera_name)
        cam_key = camera_name
        ex, ey = p["scene"]["exit_pixel"]
        exit_px = (ex / base.width_px * camera.width, camera.height - (base.height_px - ey))
        # A jittered camera is drawn larger and cut out after its motion.
        assert camera.width is not None and camera.height is not None  # presets know them
        m = jitter.margin_px(camera.width, camera.height) if jitter is not None else 0
        view = synth.View.framing(
            synth.preset_release(preset_name),
            (exit_px[0] + m, exit_px[1] + m),
            width_px=camera.width + 2 * m,
            height_px=camera.height + 2 * m,
            ifov_rad=camera.ifov_rad,
            distance_m=footprint / camera.ifov_rad,
            projection=base.projection,
        )
    background = Background.from_dict(p["scene"]["background"], seed=seed)
    if jitter is not None and background.kind == "sky":
        # The same sky per camera row: its gradient carried on over the margin.
        assert camera.width is not None and camera.height is not None  # presets know them
        m = jitter.margin_px(camera.width, camera.height)
        slope = (background.sky_bottom_K - background.sky_top_K) / (camera.height - 1)
        background = dataclasses.replace(
            background,
            sky_top_K=background.sky_top_K - m * slope,
            sky_bottom_K=background.sky_bottom_K + m * slope,
        )
    wheel = len(camera.channels) if filter_wheel else 1

    def say(f, msg):

        report(progress, f, msg)  # qogi.Cancelled when told to stop

    say(0.0, "simulating the release")
    if view is None:
        sim = synth.simulate_preset(
            preset_name,
            duration_s=duration_s,
            frame_rate_hz=(
                frame_rate_hz
                if wheel == 1
                else wheel * (frame_rate_hz or p["camera"]["frame_rate_hz"])
            ),
            seed=seed,
            num_threads=num_threads,
        )
    else:
        sim = synth.simulate(
            synth.preset_release(preset_name),
            view,
            p["duration_s"] if duration_s is None else duration_s,
            wheel * (camera.frame_rate_hz if frame_rate_hz is None else frame_rate_hz),
            seed=seed,
            num_threads=num_threads,
        )
    warm = p["camera"].get("warm_filter_temperature_K")
    out = render_recording(
        sim,
        camera,
        background,
        path,
        seed=seed,
        noise=noise,
        warm_filter_temperature_K=warm,
        camera_preset_name=cam_key,
        truth_maps=truth_maps,
        progress=lambda f, m: say(0.05 + 0.95 * f, m),
        num_threads=num_threads,
        line_shape=line_shape,
        jitter=jitter,
        filter_wheel=filter_wheel,
    )
    say(1.0, "done")
    return out
