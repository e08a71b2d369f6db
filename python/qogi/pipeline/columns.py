"""Stage 2, the column density: the contrast ``L - L_bg`` is inverted per
pixel for the Gaussian-plume parameters (:mod:`qogi.inversion`): single
channel with the gas temperature given or ambient, or several channels with
it inferred on the plume's mixing line; column density per species with its
1-sigma uncertainty and a status. Pixels on the control surfaces get the full
inversion; the velocity field around them uses a fast single-channel column
proxy (the velocimetry needs the shape of the field, not its absolute
scale), anchored to the surfaces' inverted columns. Or, for validation, the
synthetic recording's truth maps.

:func:`prepare` sets :attr:`RunState.columns`; :func:`block_columns` makes a
block's :class:`~.state.BlockColumns`.
"""

from __future__ import annotations

import math
from typing import Dict, List, Optional, Sequence

import numpy as np

from .. import _engine
from .. import workers as _workers_mod
from ..errors import Cancelled
from ..io.recording import Recording
from ..measure import inversion as inv
from ..measure.inversion import plume_depth_from_width
from ..measure.mixing_line import MixingLineSolver
from ..physics.forward import forward_model
from ..progress import fraction_part
from .background import Background
from .background_choice import pixel_sign
from .budget_terms import AlternativeModels, fractions_of, line_shape_ratios
from .config import QuantifyConfig
from .detection import significant_peak
from .sampling import _bilinear
from .selfchecks import SurfaceEvidence, upwind_mask
from .state import BlockColumns, RunState, Scene
from .surfaces import Region, Surface

__all__ = [
    "prepare",
    "block_columns",
    "TruthColumns",
    "InvertedColumns",
    "PROXY_MIN_SENSITIVITY",
    "sensitivity_weight",
    "fill_insensitive",
]

#: Below this fraction of the typical background's sensitivity (the gas's
#: contrast per column) a pixel's proxy is tapered to zero
#: (:func:`sensitivity_weight`), and a surface sample's column is
#: interpolated from its neighbours (:func:`fill_insensitive`).
PROXY_MIN_SENSITIVITY = 0.25

#: Surface samples below the inversion's detection test keep their signed
#: thin-limit column within the plume's band (InvertedColumns.plume_band),
#: whose margin beyond the significant stretch is at least this many samples.
WING_MARGIN_SAMPLES = 3


def prepare(run: RunState) -> None:
    """Sets :attr:`RunState.columns`: the truth maps' or the inversion's
    (whose scene table is built on a worker thread while frames are read)."""
    if run.cfg.methods.truth_columns:
        run.columns = TruthColumns(run.rec, run.cfg)
    else:
        run.say(0.01, "cross-section tables and the scene's inversion table")
        run.columns = InvertedColumns(
            run.rec, run.cfg, run.scene, run.roi, run.horizontal, run.background
        )
        # Where the gas does not go: the self-checks' upwind region.

        mask = upwind_mask(run.rec.width, run.rec.height, run.cfg.source, run.surfaces)
        if mask is not None:
            sl = run.roi.slices()
            run.columns.upwind_mask = mask[sl[0], sl[1]]


def sensitivity_weight(
    background: np.ndarray,
    gas_radiance: float,
    channel_sign: float,
    min_sensitivity: float = PROXY_MIN_SENSITIVITY,
) -> np.ndarray:
    """Per pixel, the factor that brings a signed contrast (gas positive by
    ``channel_sign``) over a background of band radiance ``background``
    (..., h, w) [W/(m2 sr)] towards what the same thin gas of band radiance
    ``gas_radiance`` gives over the field's median background L_ref
    (:meth:`InvertedColumns.sensitivity_weight`): the pixel's own sign
    ``sign(L_g - L_bg)`` against the channel's, times
    ``min(1, |L_g - L_ref| / |L_g - L_bg|)`` (a pixel more sensitive than
    L_ref's is brought down to it, a less sensitive one is *not* raised:
    raising multiplies its background's error too, and on the wall
    preset's shadow, half as sensitive, a weight of 2 turned +9 % into
    -91 % at 0.5 m on seed 0), tapered linearly to 0 where
    ``|L_g - L_bg| < min_sensitivity |L_g - L_ref|`` (the gas invisible,
    the noise left). Returns float32 of ``background``'s shape (1 on a
    uniform background)."""
    den = np.float32(gas_radiance) - np.asarray(background, np.float32)
    num = abs(float(np.median(den)))
    if not num > 0:
        return np.ones(den.shape, np.float32)
    a = np.abs(den)
    eps = np.float32(min_sensitivity * num)
    mag = np.minimum(np.float32(1.0), np.float32(num) / np.maximum(a, eps))
    np.minimum(mag, a / eps, out=mag)  # the taper below eps (there num / eps > 1)
    return (np.sign(den) * np.float32(channel_sign) * mag).astype(np.float32)


def fill_insensitive(cols: Dict[str, np.ndarray], sigs: Dict[str, np.ndarray], weak, first: str):
    """Replaces, in place, each frame's columns and sigmas (T, N) per
    species at the samples ``weak`` (T, N) bool by the linear interpolation
    along the surface of the other finite samples (a frame with fewer than
    two is left as it is). Returns ``(filled, total)``: the positive
    column of species ``first`` summed over the weak samples and over all
    (after filling)."""
    wk = np.asarray(weak, bool)
    idx = np.arange(wk.shape[1])
    for t in np.nonzero(wk.any(axis=1))[0]:
        for sp in cols:
            x = cols[sp][t]
            good = ~wk[t] & np.isfinite(x)
            if good.sum() < 2:
                continue
            x[wk[t]] = np.interp(idx[wk[t]], idx[good], x[good])
            sg = sigs[sp][t]
            sg[wk[t]] = np.interp(idx[wk[t]], idx[good], sg[good])
    col = np.clip(np.nan_to_num(cols[first]), 0.0, None)
    return float(col[wk].sum()), float(col.sum())


class TruthColumns:
    """Column densities from a synthetic recording's truth maps (validation:
    isolates the velocimetry and flux from the inversion)."""

    def __init__(self, rec: Recording, cfg: QuantifyConfig):
        assert rec.truth is not None  # pipeline.setup.check_inputs requires truth maps
        self.ds = {sp: rec.truth.datasets[f"column_density_kg_m2_{sp}"] for sp in cfg.species}

    def frame(self, f: int, roi: Region) -> Dict[str, np.ndarray]:
        sl = roi.slices()
        return {sp: np.asarray(d[f, sl[0], sl[1]], dtype=np.float64) for sp, d in self.ds.items()}


class InvertedColumns:
    """Column densities by the per-pixel inversion (qogi.inversion).

    Surface samples get the configured inversion (single channel with the gas
    temperature given or ambient, or every channel with the temperature
    inferred), with the plume depth sigma from the plume's width across the
    surface (axisymmetric plume) unless given. The velocity field around the
    surfaces uses a single-channel column proxy at the assumed gas
    temperature (Newton inversion, fast): velocimetry needs the field's shape,
    not its absolute scale.
    """

    def __init__(
        self,
        rec: Recording,
        cfg: QuantifyConfig,
        scene: Scene,
        roi: Region,
        horizontal: bool,
        background: Background,
    ):

        self.rec, self.cfg, self.scene, self.roi = rec, cfg, scene, roi
        self.horizontal = horizontal
        self.background = background
        channels = rec.channels
        self.model = forward_model(
            channels, cfg.species, scene.pressure_Pa, line_shape=cfg.line_shape
        )
        netd = rec.camera.netd_K or 0.02
        self.netd_K = netd  # the camera's NETD [K] the run assumes
        if cfg.gas_temperature == "infer":
            self.temperature_range_K = (scene.ambient_K - 10.0, scene.ambient_K + 150.0)
            temperature = inv.free(*self.temperature_range_K)
        else:
            self.temperature_range_K = (scene.gas_K - 10.0, scene.gas_K + 10.0)
            temperature = inv.fixed(scene.gas_K)
        # One per-scene table serves every inversion of the run. Over the
        # 160 K of an inferred temperature, 10 K nodes: the cubic spline in T
        # then differs from the 5 K table by <= 2e-3 (median 3e-6) of the
        # contrast, well inside the fast model's own 0.5 % (docs/pipeline_api.md),
        # at half the build time; and 6 nodes per decade of u = x sigma
        # instead of 8: within 0.34 NETD (99 %: 0.08) of the 8-node table on
        # the lab domain (x 1e-4 to 1, sigma 1 mm to 30 cm, 12-147 C), 22 %
        # less build time.
        # It is built on a worker thread (the engine releases the GIL) while
        # the frames are read; the first use of :attr:`table` waits for it.
        infer = cfg.gas_temperature == "infer"
        table_kw = dict(
            min_peak_temperature_K=self.temperature_range_K[0],
            max_peak_temperature_K=self.temperature_range_K[1],
            temperature_step_K=10.0 if infer else 5.0,
            nodes_per_decade=6 if infer else 8,
            num_threads=cfg.num_threads,
        )
        self._table = None

        line_solver = infer and (cfg.composition is not None or len(cfg.species) == 1)

        workers = _workers_mod.current()

        def build():
            table = inv.scene_table(
                self.model, scene.ambient_K, progress=workers.still_wanted, **table_kw
            )
            if line_solver and table is not None and workers.still_wanted():
                inv._line_inverter(table)  # its band tables, cached
            return table

        self._table_job: Optional[_workers_mod.Task] = workers.submit(build, "qogi-scene-table")
        # The other line-shape rules, for the budget's line-shape term.

        self.alternatives = AlternativeModels(
            channels, cfg.species, scene.pressure_Pa, cfg.line_shape, start=workers.start
        )
        self._line_shape_cache: Dict[tuple, tuple] = {}
        self.k_K_per_fraction: Optional[float] = None
        self.k_sigma, self.k_relative_effect = 0.0, 0.0
        self.mixing_pixels = 0
        # A known composition ties the species' fractions (then the ratios of
        # the bands' contrasts measure the temperature); otherwise each is free.
        fractions: Optional[Dict[str, object]] = None
        if cfg.composition is not None and len(cfg.species) > 1:
            ref = cfg.species[0]
            fractions = {ref: "free"}
            for sp in cfg.species[1:]:
                fractions[sp] = inv.tied(ref, cfg.composition[sp] / cfg.composition[ref])
        # Below the per-pixel test a pixel keeps its signed thin-limit column
        # (kept on the surfaces only within the plume's band: _keep_wings).
        self._inv_kw = dict(
            netd_K=netd,
            fractions=fractions,
            temperature=temperature,
            num_threads=cfg.num_threads,
            signed_below_detection=True,
        )
        self.inv_module = inv
        # The velocity proxy: a monotone lookup from the contrast of the
        # channel most sensitive to the first species to its column density,
        # at the assumed gas temperature, a typical depth and the scene's
        # background (velocimetry needs the field's shape, not its scale).
        bg_t = background.typical_temperature_K
        self._bg_t = bg_t
        contrast = self._contrast(
            {cfg.species[0]: np.array([1e-3])},
            np.array([scene.gas_K]),
            np.array([0.02]),
            use_table=False,
        )[0]
        sens = [
            abs(contrast[c]) / (netd * ch.band_radiance_derivative(bg_t))
            for c, ch in enumerate(channels)
        ]
        self.proxy_channel = int(np.argmax(sens))
        self._set_proxy_lookup(0.0 if cfg.gas_temperature == "infer" else None)
        self.sigma_m: Dict[int, float] = {}
        #: The self-diagnostics' sums per surface, over the run's blocks,
        #: and the region behind the source (set by :func:`prepare`) with
        #: its sums of squared contrast [noise^2] and pixel-frames.
        self.evidence: Dict[int, SurfaceEvidence] = {}
        self.upwind_mask: Optional[np.ndarray] = None
        self.upwind_sums = [0.0, 0]
        #: The held pixels' inpainting clip at the block's surface samples
        #: (C, N), or None (set by :meth:`finish`).
        self._held_clip: Optional[np.ndarray] = None

    def start_block(self) -> None:
        """Forgets the samples collected for the previous block (the pipeline
        streams a run in blocks); with the temperature inferred, the proxy's
        mixing line is measured again on the block."""
        for name in ("_rad", "_bg", "_prof"):
            if hasattr(self, name):
                delattr(self, name)
        if self.cfg.gas_temperature == "infer" and self._k_proxy != 0.0:
            self._set_proxy_lookup(0.0)

    def _set_proxy_lookup(self, k_K_per_fraction: Optional[float]) -> None:
        """The contrast -> column lookups of the velocity proxy: at the assumed
        gas temperature (None), or along the plume's mixing line
        T_peak = T_amb + k x once the temperature has been inferred, for a
        grid of plume depths (see :meth:`contrast_to_column`)."""
        self._k_proxy = k_K_per_fraction
        self._proxy_nodes = None  # made on first use (needs the table)
        self._grid = None

    @property
    def table(self):
        """The per-scene table (waits for the worker building it)."""
        if self._table_job is not None:
            self._table = self._table_job.result()  # re-raises the worker's error
            self._table_job = None
        return self._table

    @property
    def proxy_nodes(self):
        if self._proxy_nodes is None:
            self._proxy_nodes = self._lookup_nodes(np.array([self.cfg.sigma_m or 0.02]))[0]
        return self._proxy_nodes

    def _lookup_nodes(self, sigmas: np.ndarray) -> list:
        """(contrast, column) nodes of the monotone lookup per depth."""
        cfg, scene = self.cfg, self.scene
        x = np.geomspace(1e-7, 1.0, 64)
        if self._k_proxy is None:
            t = np.full_like(x, scene.gas_K)
        else:
            lo, hi = self.temperature_range_K
            t = np.clip(scene.ambient_K + self._k_proxy * x, lo, hi)
        # x: the released gas's total peak fraction (the mixing line's x).
        fr = {cfg.species[0]: x}
        if cfg.composition is not None:
            total = sum(cfg.composition[sp] for sp in cfg.species)
            fr = {sp: x * cfg.composition[sp] / total for sp in cfg.species}
        n, m = len(sigmas), len(x)
        frs = {sp: np.tile(v, n) for sp, v in fr.items()}
        ts = np.tile(t, n)
        sg = np.repeat(np.asarray(sigmas, float), m)
        contrast = np.abs(self._contrast(frs, ts, sg)[:, self.proxy_channel]).reshape(n, m)
        cols = np.asarray(self.model.column_density(frs, ts, sg, scene.ambient_K)[cfg.species[0]])
        cols = cols.reshape(n, m)
        out = []
        for i in range(n):
            keep = np.concatenate([[True], np.diff(contrast[i]) > 0])
            out.append(
                (np.concatenate([[0.0], contrast[i][keep]]), np.concatenate([[0.0], cols[i][keep]]))
            )
        return out

    def line_shape_curves(self, j: int, species: str):
        """(columns, ratios) of :func:`qogi.pipeline.budget_terms.line_shape_ratios` for
        surface ``j``: the proxy channel, the surface's depth, the assumed
        gas temperature or the fitted mixing line (computed once per surface
        and species, or once per surface with a known composition;
        :meth:`prepare_line_shape_curves` computes them side by side)."""
        cols, ratios = self._line_shape_job(j, species)()
        return cols[species], ratios

    def prepare_line_shape_curves(self, surfaces: Sequence[int], species: Sequence[str]) -> None:
        """Compute the line-shape curves of every surface and species on
        threads (the engine's band radiance releases the GIL) before the
        budget reads them one by one."""
        from concurrent.futures import ThreadPoolExecutor

        jobs = {}
        for j in surfaces:
            for sp in species:
                key = self._line_shape_key(j, sp)
                if key not in self._line_shape_cache and key not in jobs:
                    jobs[key] = self._line_shape_job(j, sp)
        if len(jobs) < 2:
            return

        threads = min(len(jobs), _engine.resolve_threads(self.cfg.num_threads or 0))
        with ThreadPoolExecutor(threads, thread_name_prefix="qogi-line-shape") as pool:
            for f in [pool.submit(job) for job in jobs.values()]:
                try:
                    f.result()
                except (ValueError, RuntimeError, OSError):
                    pass  # raised again (and reported) when the budget reads it

    def _line_shape_key(self, j: int, species: str) -> tuple:
        # A known composition gives every species the same plumes.
        return (j, None if self.cfg.composition else species)

    def _line_shape_job(self, j: int, species: str):
        """A call returning (and caching) the surface's curves for all
        species: ({species: columns}, ratios)."""

        key = self._line_shape_key(j, species)
        cache = self._line_shape_cache

        def job():
            if key not in cache:
                cfg, scene = self.cfg, self.scene

                def temperature(x):
                    if self.k_K_per_fraction is None:
                        return np.full_like(x, scene.gas_K)
                    lo, hi = self.temperature_range_K
                    return np.clip(scene.ambient_K + self.k_K_per_fraction * x, lo, hi)

                cache[key] = line_shape_ratios(
                    self.model,
                    [m for _, m in self.alternatives.get()],
                    self.proxy_channel,
                    fractions_of(cfg, species),
                    temperature,
                    self.sigma_m.get(j, cfg.sigma_m or 0.02),
                    scene.ambient_K,
                    self._bg_t,
                )
            return cache[key]

        return job

    def _contrast(
        self,
        fractions: Dict[str, np.ndarray],
        peak_temperature_K: np.ndarray,
        sigma_m: np.ndarray,
        use_table: bool = True,
    ) -> np.ndarray:
        """Contrast (N, C) [W/(m2 sr)] of Gaussian plumes in front of the
        scene's typical background: from the per-scene table when there is
        one (thousands of times faster), else from the fast model."""
        tp = np.asarray(peak_temperature_K, float)
        sg = np.asarray(sigma_m, float)
        if use_table and self.table is not None:
            x = np.stack(
                [
                    np.asarray(fractions.get(sp, np.zeros_like(tp)), float)
                    for sp in self.cfg.species
                ],
                axis=1,
            )
            tbg = np.full((tp.size, len(self.rec.channels)), float(self._bg_t))
            return np.asarray(self.table.contrast(np.ascontiguousarray(x), tp, sg, tbg)[0])
        rad = self.model.band_radiance(fractions, tp, sg, self.scene.ambient_K, self._bg_t)
        return rad - np.array([ch.band_radiance(self._bg_t) for ch in self.rec.channels])

    def plume_band(self, j: int) -> np.ndarray:
        """The samples of surface ``j`` that hold the plume (bool, N_j): from
        the first to the last whose time-averaged contrast is significant
        (:func:`qogi.pipeline.detection.significant_peak`, the test of the
        detection limit's width), widened on each side by that stretch's own
        length, at least :data:`WING_MARGIN_SAMPLES`; none where no sample
        is significant (or no profile was stored)."""
        snr = self.mean_contrast_snr(j)
        if snr is None:
            return np.zeros(0, bool)
        n = len(snr)
        band = np.zeros(n, bool)
        sig = np.nonzero(np.nan_to_num(snr) >= significant_peak(n))[0]
        if sig.size:
            lo, hi = int(sig[0]), int(sig[-1])
            w = max(WING_MARGIN_SAMPLES, hi - lo + 1)
            band[max(0, lo - w) : min(n, hi + w + 1)] = True
        return band

    def _keep_wings(self, res_cols, status, edges, res_sig) -> None:
        """The inversion gave every pixel-frame below its detection test its
        signed thin-limit column (``signed_below_detection``): kept within
        each surface's :meth:`plume_band` (the plume's faint wings, whose
        columns the test would zero: a faint plume then read low, the more
        the fainter, -80 % at half its detection limit), set to 0 beyond it
        (there it would only add noise, and the background's error summed
        along the surface). A temporal percentile background stands the
        noise's own percentile towards the gas's side
        (:meth:`Background.noise_pedestal`, measured); that pedestal, hidden
        where the test zeroes, is taken out of the kept columns (its column:
        the pedestal in the proxy channel's noise units x the sample's
        noise-equivalent column; exact with one channel): on
        `wall-absorption` it added 4-8 points. ``res_cols`` {species:
        (T, N)} in place, ``status`` and ``res_sig`` {species: (T, N)} the
        inversion's."""
        below = status == self.inv_module.BELOW_DETECTION
        # The percentile's pedestal in the proxy channel's noise units (its
        # column: that many noise-equivalent columns, the samples' sigma).
        ped = self.background.noise_pedestal()
        pedestal = 0.0
        if ped is not None:
            noise = self.proxy_noise()
            pedestal = float(ped[self.proxy_channel]) / noise if noise > 0 else 0.0
        for j in range(len(edges) - 1):
            a, b = edges[j], edges[j + 1]
            band = self.plume_band(j)
            if band.size != b - a:
                band = np.zeros(b - a, bool)
            off = below[:, a:b] & ~band[None, :]
            on = below[:, a:b] & band[None, :]
            for sp in self.cfg.species:
                part = res_cols[sp][:, a:b]
                part[off] = 0.0
                if pedestal > 0:
                    part[on] -= pedestal * res_sig[sp][:, a:b][on]
                res_cols[sp][:, a:b] = part

    def proxy_noise(self) -> float:
        """The proxy channel's per-frame NETD noise [radiance] over the
        typical background."""
        c = self.proxy_channel
        netd = np.broadcast_to(np.asarray(self._inv_kw["netd_K"], float), (len(self.rec.channels),))
        return float(netd[c]) * float(self.rec.channels[c].band_radiance_derivative(self._bg_t))

    def mean_contrast_snr(self, j: int) -> Optional[np.ndarray]:
        """The time-averaged proxy-channel contrast along surface ``j`` in
        units of its noise (per-frame NETD noise / sqrt(frames)); None
        without stored profiles."""
        prof = getattr(self, "_prof", None)
        if not prof:
            return None
        noise = self.proxy_noise() / math.sqrt(len(prof))
        return np.mean([p[j] for p in prof], axis=0) / noise

    def _lookup(self, contrast, nodes=None) -> np.ndarray:
        c = np.asarray(contrast)
        nc, ncol = nodes if nodes is not None else self.proxy_nodes
        return np.sign(c) * np.interp(np.abs(c), nc, ncol)

    def contrast_to_column(self, contrast: np.ndarray) -> np.ndarray:
        """Signed proxy contrast fields (T, H, W) -> column proxy, in place.

        The velocimetry's mass balance needs a field proportional to the
        column all along the plume, and a single-channel lookup depends on the
        plume's depth (saturation): the depth grows downstream. Without a
        given depth, each line across the plume (rows for horizontal
        surfaces, columns otherwise) gets the lookup of its own depth, the
        Gaussian width of the time-averaged plume across that line
        (axisymmetric plume), interpolated between lookups on a grid of
        depths; lines without a measurable plume take the nearest line's."""
        if self.cfg.sigma_m is not None or contrast.shape[0] == 0:
            for k in range(contrast.shape[0]):
                contrast[k] = self._lookup(contrast[k])
            return contrast
        view = contrast if self.horizontal else contrast.transpose(0, 2, 1)
        mean = self._lookup(view.mean(axis=0))  # (lines, across)
        top = mean.max()
        lines = np.arange(mean.shape[0])
        seen = (mean.max(axis=1) > 0.05 * top) if top > 0 else np.zeros(len(lines), bool)
        widths = np.where(seen, plume_depth_from_width(mean, self.scene.pixel_m), np.nan)
        ok = np.isfinite(widths) & (widths > 0)
        if not ok.any():
            for k in range(contrast.shape[0]):
                contrast[k] = self._lookup(contrast[k])
            return contrast
        widths = np.interp(lines, lines[ok], widths[ok])
        grid = np.geomspace(0.002, 0.5, 9)
        nodes = self._lookup_nodes(grid)
        u = np.interp(
            np.log(np.clip(widths, grid[0], grid[-1])), np.log(grid), np.arange(grid.size)
        )
        j0 = np.minimum(np.floor(u).astype(int), grid.size - 2)
        self.line_depths_m = widths

        # Every value through its line's two depth lookups (the engine's
        # LookupLines: numpy.interp per node table, blended per line), on a
        # contiguous copy when the field is a view.
        m = max(len(c) for c, _ in nodes)
        xs = np.array([np.pad(c, (0, m - len(c)), mode="edge") for c, _ in nodes])
        ys = np.array([np.pad(k, (0, m - len(k)), mode="edge") for _, k in nodes])
        work = (
            contrast
            if (contrast.flags.c_contiguous and contrast.dtype == np.float32)
            else np.ascontiguousarray(contrast, dtype=np.float32)
        )
        _engine.lookup_lines(
            work,
            bool(self.horizontal),
            xs,
            ys,
            j0.astype(np.int32),
            np.clip(u - j0, 0.0, 1.0),
            num_threads=self.cfg.num_threads,
        )
        if work is not contrast:
            contrast[...] = work
        return contrast

    def proxy_field(
        self,
        frame: np.ndarray,
        out: Optional[np.ndarray] = None,
        frame_ids: Optional[Sequence[int]] = None,
    ) -> np.ndarray:
        """The signed proxy-channel contrast of frames (..., C, H, W) over the
        region -> (..., h, w) float32 (into ``out`` when given); ``frame_ids``
        the frames' indices (a drifting background changes with time)."""
        return self._signed_contrast(frame, out, frame_ids)[0]

    def sensitivity_weight(self, background: np.ndarray) -> np.ndarray:
        """Per pixel, the factor that brings the signed proxy contrast over a
        background of band radiance ``background`` (..., h, w) [W/(m2 sr)] to
        what the same gas gives over the region's typical background (within
        the limits of :func:`sensitivity_weight`).

        A thin gas layer at temperature T_g changes the radiance by
        tau (L(T_g) - L_bg) (thesis eq. 4, optically thin): over a pixel
        whose background is hotter than the gas (a hot pipe behind a plume
        that emits elsewhere) the same column absorbs. One contrast -> column
        lookup for the whole field (:meth:`contrast_to_column`) then reads
        such gas as a negative column, and a background near the gas's
        temperature as none: a static pattern of the background's that the
        velocimetry follows. The factor (:func:`sensitivity_weight`, L_ref
        the field's median background; 1 on a uniform background, as
        before) flips the sign where the gas absorbs instead of emitting,
        brings a more sensitive pixel down to L_ref's sensitivity and tapers
        a pixel the gas hardly changes (below
        :data:`PROXY_MIN_SENSITIVITY` of L_ref's) to zero. The field is
        already signed by the channel; the factor is relative to that.
        Returns float32 of ``background``'s shape."""
        c = self.proxy_channel
        return sensitivity_weight(
            background,
            float(self.rec.channels[c].band_radiance(self.scene.gas_K)),
            float(self.background.channel_sign[c]),
        )

    def _signed_contrast(
        self,
        frame: np.ndarray,
        out: Optional[np.ndarray] = None,
        frame_ids: Optional[Sequence[int]] = None,
    ):
        """:meth:`proxy_field` and the proxy channel's background behind it
        (h, w) or (..., h, w)."""
        sl = self.roi.slices()
        c = self.proxy_channel
        # In float32 (the frames' own precision; its rounding, ~1e-7 of the
        # radiance, is ~1e-4 of the NETD noise).
        fr = frame[..., c, sl[0], sl[1]]
        bg = self.background.field(fr, self.horizontal, channel=c, frame_ids=frame_ids)
        if bg is None:  # a uniform region background
            assert isinstance(self.cfg.background, Region)  # field() is None only for a region
            bg = self.background.region_mean(frame, self.cfg.background)[..., c, None, None]
        # Signed (gas contrast positive): noise averages out of the sums the
        # velocimetry's flux level takes along the plume.
        dl = np.subtract(fr, bg, out=out, dtype=np.float32)
        dl *= np.float32(self.background.channel_sign[c])
        return dl, bg

    def collect(
        self,
        frames: np.ndarray,
        surfaces: Sequence[Surface],
        samples,
        out: Optional[np.ndarray] = None,
        first: int = 0,
    ) -> np.ndarray:
        """The signed proxy-channel contrast fields (B, h, w) of a block of
        frames (B, C, H, W), the recording's frames ``first`` on (into
        ``out`` when given), converted to a column
        proxy by :meth:`contrast_to_column` once the lookup is final; stores
        the radiance and the background at the surface samples for
        :meth:`finish`."""
        ids = range(first, first + len(frames))
        field, bg_field = self._signed_contrast(frames, out, frame_ids=ids)
        if self.upwind_mask is not None:
            up = field[..., self.upwind_mask].astype(float) / self.proxy_noise()
            self.upwind_sums[0] += float(np.sum(up * up))
            self.upwind_sums[1] += int(up.size)
        # The contrast as over the typical background (a pipe hotter than the
        # gas, a wall near its temperature): the column's pattern, not the
        # background's, for the velocimetry and the surfaces' depth.
        field *= self.sensitivity_weight(bg_field)
        origin = [self.roi.x0, self.roi.y0]
        rad, bg, prof = [], [], []
        for s, (xy, _n, _dl, t) in zip(surfaces, samples):
            rad.append(_bilinear(frames, xy))
            bg.append(self.background.along(frames, s, xy, t, frame_ids=ids))
            prof.append(_bilinear(field, xy - origin))
        if not hasattr(self, "_rad"):
            self._rad: List[np.ndarray] = []
            self._bg: List[np.ndarray] = []
            self._prof: List[List[np.ndarray]] = []
        self._rad.extend(np.concatenate(rad, axis=-1))
        self._bg.extend(np.concatenate(bg, axis=-1))
        self._prof.extend([p[i] for p in prof] for i in range(len(frames)))
        return field

    def finish(self, samples, time_averaged: bool = False, progress=None, alongside=None):
        """Inverts the stored samples of every frame in one call. Returns per
        surface ``(columns {sp: (T, N)}, sigmas {sp: (T, N)})`` and the status
        counts. ``alongside`` (optional callable) runs on a worker thread while
        the per-pixel solve runs once the proxy lookup is final (with the
        temperature inferred), else after it; its exception is re-raised.
        The plume depth of each surface is the Gaussian width of its
        time-averaged proxy column profile (axisymmetric plume), unless given."""

        nt = len(self._rad)
        sizes = [len(x[0]) for x in samples]
        edges = np.concatenate([[0], np.cumsum(sizes)])
        sig = np.empty(edges[-1])
        for j in range(len(samples)):
            if self.cfg.sigma_m is not None:
                sigma = self.cfg.sigma_m
            else:
                mean_prof = np.mean([self._lookup(p[j]) for p in self._prof], axis=0)
                sigma = float(plume_depth_from_width(mean_prof, self.scene.pixel_m))
                if not (np.isfinite(sigma) and sigma > 0):
                    sigma = 0.02
            self.sigma_m[j] = float(sigma)
            sig[edges[j] : edges[j + 1]] = sigma
        rad = np.asarray(self._rad)  # (T, C, N)
        bg = np.asarray(self._bg)
        # Where the held pixels' inpainting was bounded by their percentile,
        # by how much (C, N): the background residual's evidence.
        clips = [self.background.held_clip_at(x[0]) for x in samples]
        self._held_clip = (
            None
            if all(c is None for c in clips)
            else np.concatenate(
                [
                    np.zeros((rad.shape[1], len(x[0]))) if c is None else c
                    for c, x in zip(clips, samples)
                ],
                axis=-1,
            )
        )
        # The plume depth: given, or the width of the time-averaged plume
        # across each surface (axisymmetric plume), held fixed with one
        # channel and as a Gaussian prior (50 %) when the temperature is
        # inferred (a free depth is nearly degenerate with the fractions).
        if self.cfg.sigma_m is not None or self.cfg.gas_temperature != "infer":
            sigma_param = inv.fixed(float(np.median(sig)))
            sigma_pixels = sig
        else:
            sigma_param = None
            sigma_pixels = sig
        if self.cfg.gas_temperature == "infer" and not time_averaged:
            return self._finish_mixing(rad, bg, sig, edges, len(samples), progress, alongside)
        if time_averaged:
            res = self._invert(
                rad.mean(axis=0),
                bg.mean(axis=0),
                sigma_pixels,
                sigma_param,
                noise_scale=1.0 / math.sqrt(nt),
                progress=progress,
            )
            res_cols = {
                sp: np.repeat(res.column_density[sp][None], nt, axis=0) for sp in self.cfg.species
            }
            res_sig = {
                sp: np.repeat(res.column_density_sigma[sp][None], nt, axis=0)
                for sp in self.cfg.species
            }
            ok = np.repeat((res.valid | (res.status == inv.BELOW_DETECTION))[None], nt, axis=0)
            counts = res.counts()
        else:
            # Every frame's pixels in one call, each from the coarse table
            # guess: warm starts from the previous frame can follow the wrong
            # branch of the temperature-column ambiguity of hot plumes.
            c_, n_ = rad.shape[1], rad.shape[2]
            flat = self._invert(
                rad.transpose(1, 0, 2).reshape(c_, nt * n_),
                bg.transpose(1, 0, 2).reshape(c_, nt * n_),
                np.tile(sigma_pixels, nt),
                sigma_param,
                1.0,
                progress,
            )
            res_cols = {sp: flat.column_density[sp].reshape(nt, n_) for sp in self.cfg.species}
            res_sig = {sp: flat.column_density_sigma[sp].reshape(nt, n_) for sp in self.cfg.species}
            ok = (flat.valid | (flat.status == inv.BELOW_DETECTION)).reshape(nt, n_)
            counts = flat.counts()
        status = (
            np.repeat(res.status[None], nt, axis=0)
            if time_averaged
            else flat.status.reshape(nt, rad.shape[2])
        )
        self._note_evidence(rad, bg, status, edges)
        self._keep_wings(res_cols, status, edges, res_sig)
        out = []
        for j in range(len(samples)):
            a, b = edges[j], edges[j + 1]
            cols = {
                sp: np.where(ok[:, a:b], res_cols[sp][:, a:b], np.nan) for sp in self.cfg.species
            }
            sigs = {sp: np.where(ok[:, a:b], res_sig[sp][:, a:b], 0.0) for sp in self.cfg.species}
            out.append((cols, sigs))
        self._fill_insensitive(out, bg, edges)
        if alongside is not None:
            alongside()
        return out, counts

    # -- the inferred gas temperature, frame by frame -----------------------------
    def _finish_mixing(self, rad, bg, sig, edges, n_surfaces, progress, alongside=None):
        """Per-frame columns with the gas temperature inferred through the
        plume's mixing line (:class:`qogi.measure.mixing_line.MixingLineSolver`:
        the line's slope k measured once for the scene, then every
        pixel-frame solved on the line). Sets :attr:`k_K_per_fraction`,
        :attr:`k_sigma`, :attr:`mixing_pixels` and :attr:`k_relative_effect`
        (the uncertainty of k carried into the column-density term)."""
        cfg = self.cfg
        nt, nc, n = rad.shape
        kw = dict(self._inv_kw)
        kw.pop("temperature")
        solver = MixingLineSolver(
            self.model,
            self.table,
            rad.transpose(1, 0, 2).reshape(nc, nt * n),
            bg.transpose(1, 0, 2).reshape(nc, nt * n),
            np.tile(sig, nt),
            ambient_K=self.scene.ambient_K,
            temperature_range_K=self.temperature_range_K,
            species=cfg.species,
            composition=cfg.composition,
            inversion_options=kw,
        )

        found = solver.slope(fraction_part(progress, 0.0, 0.3))
        self.k_K_per_fraction, self.k_sigma, self.mixing_pixels = 0.0, 0.0, 0
        if found is not None:
            self.mixing_pixels = found.num_samples
            if found.found:
                self.k_K_per_fraction = found.slope_K_per_fraction
                self.k_sigma = found.sigma_K_per_fraction
        k = self.k_K_per_fraction
        self._set_proxy_lookup(k)

        # What needs the final lookup (the proxy field's conversion) runs on a
        # worker thread alongside the per-pixel solve.
        job = None
        if alongside is not None:
            _ = self.proxy_nodes  # made here, before the worker uses it
            job = _workers_mod.current().submit(alongside, "qogi-proxy")
        try:
            flat = solver.solve(k, np.arange(nt * n), fraction_part(progress, 0.3, 0.9))
        finally:
            if job is not None:
                job.wait()
        if job is not None:
            job.result()  # re-raises the worker's error
        # Sensitivity to k on every 5th frame: carried into the column term.
        sub = (np.arange(0, nt, 5)[:, None] * n + np.arange(n)[None, :]).ravel()
        self.k_relative_effect = solver.slope_effect(
            flat, k, self.k_sigma, sub, fraction_part(progress, 0.9, 1.0)
        )
        inv = self.inv_module
        res_cols = {sp: flat.column_density[sp].reshape(nt, n) for sp in cfg.species}
        res_sig = {sp: flat.column_density_sigma[sp].reshape(nt, n) for sp in cfg.species}
        ok = (flat.valid | (flat.status == inv.BELOW_DETECTION)).reshape(nt, n)
        self._keep_wings(res_cols, flat.status.reshape(nt, n), edges, res_sig)
        out = []
        for j in range(n_surfaces):
            a, b = edges[j], edges[j + 1]
            cols = {sp: np.where(ok[:, a:b], res_cols[sp][:, a:b], np.nan) for sp in cfg.species}
            sigs = {sp: np.where(ok[:, a:b], res_sig[sp][:, a:b], 0.0) for sp in cfg.species}
            out.append((cols, sigs))
        self._note_evidence(rad, bg, flat.status.reshape(nt, n), edges)
        self._fill_insensitive(out, bg, edges)
        return out, flat.counts()

    def _fill_insensitive(self, out, bg, edges) -> None:
        """Where a surface sample's background is so near the gas's own
        radiance that the gas hardly changes it (``|L(T_g) - L_bg|`` below
        :data:`PROXY_MIN_SENSITIVITY` of the typical background's, in the
        proxy channel: the edge of a pipe as hot as the gas), its column is
        the noise amplified (thesis eq. 4: the contrast is
        tau (L(T_g) - L_bg)); it is replaced, per frame, by the linear
        interpolation along the surface of its neighbours' (columns and
        sigmas), and the share of the surface's column so filled is noted
        in the evidence (``insensitive_fraction``, a self-check). ``out``
        the per-surface ``(columns, sigmas)`` (T, N_j) per species, changed
        in place; ``bg`` (T, C, N) the background at the samples."""
        c = self.proxy_channel
        ch = self.rec.channels[c]
        l_gas = float(ch.band_radiance(self.scene.gas_K))
        ref = abs(l_gas - float(ch.band_radiance(self._bg_t)))
        if not ref > 0:
            return
        weak = np.abs(l_gas - bg[:, c, :]) < PROXY_MIN_SENSITIVITY * ref  # (T, N)
        first = self.cfg.species[0]
        for j, (cols, sigs) in enumerate(out):
            wk = weak[:, edges[j] : edges[j + 1]]
            filled, total = fill_insensitive(cols, sigs, wk, first)
            ev = self.evidence.setdefault(j, SurfaceEvidence())
            ev.insensitive_column += filled
            ev.column_sum += total

    def _note_evidence(self, rad, bg, status, edges) -> None:
        """Adds a block's self-diagnostic sums per surface
        (:class:`qogi.pipeline.selfchecks.SurfaceEvidence`): the proxy channel's
        sign-aware contrast (T, C, N radiance and background) in units of
        its NETD noise, and the inversion's status (T, N)."""
        c = self.proxy_channel
        noise = self.proxy_noise()
        # The gas's sign per sample from its background (a hot pipe: absorbed).
        sign = pixel_sign(
            bg[None, :, c, :],
            np.array([self.rec.channels[c].band_radiance(self.scene.gas_K)]),
            self.background.channel_sign[c : c + 1],
        )[0]
        contrast = (rad[:, c, :] - bg[:, c, :]) * (sign / noise)
        # The background's residual is judged on the held pixels'
        # inpainting before its bound (inpaint_held): the bound makes the
        # background agree with the frames' floor there, and by how much it
        # had to is what they show of its error.
        clip = self._held_clip
        floor = contrast if clip is None else contrast - clip[c][None, :] / noise
        at_bound = status == self.inv_module.AT_BOUND
        for j in range(len(edges) - 1):
            a, b = edges[j], edges[j + 1]
            ev = SurfaceEvidence.of(contrast[:, a:b], at_bound[:, a:b], floor[:, a:b])
            self.evidence.setdefault(j, SurfaceEvidence()).__iadd__(ev)

    def _invert(self, rad, bg, sigma_pixels, sigma_param, noise_scale, progress):
        """One inversion call; with an inferred temperature and no given depth,
        a Gaussian prior on sigma centred on each pixel's width estimate."""
        inv = self.inv_module
        if sigma_param is None:
            # The prior's centre varies per surface: group the pixels by it.
            out = None
            res_all = {}
            for val in np.unique(sigma_pixels):
                sel = sigma_pixels == val
                inversion = inv.Inversion(
                    self.model,
                    self.scene.ambient_K,
                    sigma_m=inv.prior(float(val), 0.5 * float(val), 1e-3, 0.5),
                    table=self.table,
                    **self._inv_kw,
                )
                res_all[float(val)] = (
                    sel,
                    inversion.invert(rad, background_radiance=bg, mask=sel, progress=progress),
                )
            # Merge: each pixel from the run that selected it.
            sels = list(res_all.values())
            out = sels[0][1]
            for sel, r in sels[1:]:
                out = inv.merge_results(out, r, sel)
            return out
        inversion = inv.Inversion(
            self.model,
            self.scene.ambient_K,
            sigma_m=sigma_param,
            table=self.table,
            **self._inv_kw,
        )
        if noise_scale != 1.0:
            return inversion.invert_mean(
                rad[None] if rad.ndim == 2 else rad,
                background_radiance=bg,
                sigma_m=sigma_pixels,
                progress=progress,
            )
        return inversion.invert(
            rad, background_radiance=bg, sigma_m=sigma_pixels, progress=progress
        )


def _anchor_proxy(
    fields: np.ndarray, samples, surf_cols, species: str, horizontal: bool, roi: Region
) -> Dict[str, float]:
    """Scales the velocity proxy (T, H, W) line by line to the inverted
    columns where both exist: along each surface, the ratio of the full
    inversion's column sum to the proxy's (over every frame) is the proxy's
    calibration there; lines between surfaces take it interpolated, lines
    beyond the outermost surfaces the nearest one's. The velocimetry's mass
    balance needs the proxy proportional to the column along the plume, which
    a single-channel lookup cannot promise where the gas cools and thins.
    Returns {line: ratio} of the anchors (for the record)."""
    pos, ratio = [], []
    for (xy, _n, _dl, _t), cols in zip(samples, surf_cols):
        inv = cols[species][: fields.shape[0]]
        good = np.isfinite(inv)
        if not good.any():
            continue
        prox = np.stack(
            [_bilinear(fields[k], xy - [roi.x0, roi.y0]) for k in range(fields.shape[0])]
        )
        a, b = float(np.sum(np.where(good, inv, 0.0))), float(np.sum(np.where(good, prox, 0.0)))
        if a > 0 and b > 0:
            pos.append(float(np.mean(xy[:, 1] - roi.y0 if horizontal else xy[:, 0] - roi.x0)))
            ratio.append(a / b)
    if not pos:
        return {}
    order = np.argsort(pos)
    pos_a, ratio_a = np.asarray(pos)[order], np.asarray(ratio)[order]
    view = fields if horizontal else fields.transpose(0, 2, 1)
    lines = np.arange(view.shape[1])
    scale = np.exp(np.interp(lines, pos_a, np.log(ratio_a))).astype(np.float32)
    view *= scale[None, :, None]
    return {f"{p:.0f}": float(r) for p, r in zip(pos_a, ratio_a)}


def block_columns(st: RunState, blk, say) -> BlockColumns:
    """The column field over the region and the columns along the surfaces
    of the frames of one block (``blk``, a :class:`qogi.pipeline.timebase.Block`).
    A cancel (:class:`qogi.Cancelled` from ``say``) keeps what was read:
    the frames collected so far are inverted (unless that is cancelled too)
    and the block comes back with ``cancelled`` set."""
    rec, cfg, roi, samples, columns = st.rec, st.cfg, st.roi, st.samples, st.columns
    a, b = blk.read
    nb = b - a
    first = st.start + a
    col_fields = np.zeros((nb, roi.y1 - roi.y0, roi.x1 - roi.x0), dtype=np.float32)
    surf_cols = [{sp: np.full((nb, len(x[0])), np.nan) for sp in cfg.species} for x in samples]
    surf_sig = [{sp: np.zeros((nb, len(x[0]))) for sp in cfg.species} for x in samples]
    counts: Dict[str, int] = {}
    info: Dict[str, object] = {}
    done = 0
    if isinstance(columns, InvertedColumns):
        columns.start_block()

    def invert_collected(n_done: int, time_averaged: bool, alongside=None) -> None:
        if cfg.methods.truth_columns or n_done == 0:
            return
        per_surface, cnt = columns.finish(
            samples,
            time_averaged=time_averaged,
            progress=lambda fr_: say(0.35 + 0.25 * fr_, "inverting the surfaces' pixels"),
            alongside=alongside,
        )
        for j in range(len(samples)):
            for sp in cfg.species:
                surf_cols[j][sp][:n_done] = per_surface[j][0][sp]
                surf_sig[j][sp][:n_done] = per_surface[j][1][sp]
        for key, v in cnt.items():
            counts[key] = counts.get(key, 0) + int(v)

    def out(cancelled: bool = False) -> BlockColumns:
        return BlockColumns(col_fields, surf_cols, surf_sig, counts, done, info, cancelled)

    time_averaged = cfg.methods.time_averaged
    try:
        if cfg.methods.truth_columns:
            acc: Dict[str, np.ndarray] = {}  # the truth columns' sum (time-averaged order)
            for k in range(nb):
                fields = columns.frame(first + k, roi)
                if time_averaged:
                    acc = fields if k == 0 else {sp: acc[sp] + fields[sp] for sp in fields}
                col_fields[k] = sum(fields.values())
                for j, (xy, _n, _dl, _t) in enumerate(samples):
                    for sp in cfg.species:
                        surf_cols[j][sp][k] = _bilinear(fields[sp], xy - [roi.x0, roi.y0])
                counts["converged"] = counts.get("converged", 0) + sum(len(x[0]) for x in samples)
                done = k + 1
                say(0.05 + 0.3 * done / nb, f"column field, frame {done}/{nb}")
        else:
            # Sub-blocks of frames: one read and one vectorised pass each (at
            # least ten, for the progress and a cancel's partial result).
            sub = int(np.clip(nb // 10, 1, 25))
            for k in range(0, nb, sub):
                m = min(sub, nb - k)
                fr = rec.frames(first + k, first + k + m, quantity="radiance")
                st.radiance_check(fr, first + k)
                columns.collect(
                    fr, st.surfaces, samples, out=col_fields[k : k + m], first=first + k
                )
                done = k + m
                say(0.05 + 0.3 * done / nb, f"background and column field, frame {done}/{nb}")
        if time_averaged and cfg.methods.truth_columns:
            for j, (xy, _n, _dl, _t) in enumerate(samples):
                for sp in cfg.species:
                    surf_cols[j][sp][:] = _bilinear(acc[sp] / nb, xy - [roi.x0, roi.y0])
        # The proxy field over the whole region (the flow runs on its part,
        # crop; the flux level's transport balance on all of it) is turned
        # into a column alongside the surfaces' final solve.
        part = col_fields[:done]
        invert_collected(done, time_averaged, alongside=lambda: columns.contrast_to_column(part))
        if not cfg.methods.truth_columns:
            info["proxy_anchor"] = _anchor_proxy(
                part, samples, surf_cols, cfg.species[0], st.horizontal, roi
            )
    except Cancelled:
        try:
            invert_collected(done, time_averaged)
        except Cancelled:
            pass
        return out(cancelled=True)
    return out()
