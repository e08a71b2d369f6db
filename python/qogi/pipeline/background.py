"""Stage 1, the background: the gas-free band radiance of each channel,
beside each control surface, a temporal percentile, or a static and a
drifting layer where the background moves on its own (chosen from the scene
by default, :func:`qogi.pipeline.background_choice.choose`), or from a user region.

(:mod:`qogi.pipeline.background_choice` holds the choice's physics; this module is the
pipeline's stage that applies it to a run.)"""

from __future__ import annotations

from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

from .. import _engine
from ..io.recording import Recording
from .background_choice import (
    _noise,
    _relative_to_contrast,
    choose,
    held_background_error,
    inpaint_held,
    percentile_background,
)
from .config import QuantifyConfig
from .sampling import _bilinear
from .state import RunState
from .surfaces import Region, Surface, _smooth_background

__all__ = ["Background", "prepare"]


def prepare(run: RunState) -> None:
    """Chooses the run's background method and sets :attr:`RunState.background`
    (its static shape from the sampled frames)."""
    bg_cfg, run.info["background_choice"] = _choose_background(
        run.cfg, run.sample_frames, run.surfaces, run.samples, run.channel_sign
    )
    background = Background(
        run.rec,
        bg_cfg,
        run.roi,
        run.frames,
        run.channel_sign,
        run.say,
        run.background_temperature_K,
        run.scene.gas_K,
    )
    if bg_cfg.background == "drifting":
        run.info["background_drift"] = background.drift
        choice = run.info["background_choice"]
        if isinstance(choice, dict) and run.sample_frames is not None:
            choice["relative"] = background.drifting_relative(
                run.sample_frames, _sample_ids(run.frames), run.samples
            )
    if not isinstance(bg_cfg.background, Region) and bg_cfg.background not in (
        "percentile",
        "drifting",
    ):
        sl = run.roi.slices()
        # setup.prepare samples frames for every method but a region and the percentile.
        assert run.sample_frames is not None
        background.set_static_shape(run.sample_frames[:, :, sl[0], sl[1]].mean(axis=0))
    run.background = background


def _sample_ids(frames: range) -> List[int]:
    """The frame indices of the run's sampled frames (as setup takes them)."""
    return list(frames)[:: max(1, len(frames) // 50)][:50]


def _choose_background(cfg: QuantifyConfig, sample_frames, surfaces, samples, channel_sign):
    """The background method of the run: ``"auto"`` chooses between beside
    the surfaces and the temporal percentile from the scene
    (:func:`qogi.pipeline.background_choice.choose`). Returns (the config the background
    stage uses, the choice's record for ``info``, or None)."""
    if cfg.background != "auto":
        return cfg, None

    if sample_frames is None or len(sample_frames) < 2:
        # No frame-to-frame noise to test the strips with: the strips beside
        # the surfaces (the estimate that needs no time series).
        return cfg.replace(background="beside-surface"), {
            "method": "beside-surface",
            "reason": "fewer than 2 frames: the strips not tested",
            "strips": [],
            "relative": {},
            "not_gas_free": [],
        }
    choice = choose(sample_frames, surfaces, samples, channel_sign, cfg.background_percentile)
    return cfg.replace(background=choice["method"]), choice


class Background:
    """Gas-free band radiance per channel: along each surface's samples and on
    the analysis region (the latter for the velocity field)."""

    def __init__(
        self,
        rec: Recording,
        cfg: QuantifyConfig,
        roi: Region,
        frames: range,
        channel_sign: np.ndarray,
        say,
        typical_temperature_K: float,
        gas_temperature_K: Optional[float] = None,
    ):
        self.cfg = cfg
        self.roi = roi
        self.channel_sign = np.asarray(channel_sign, dtype=float)
        self.typical_temperature_K = typical_temperature_K
        self.percentile_img: Optional[np.ndarray] = None
        self._pedestal: Optional[np.ndarray] = None
        #: Pixels of the region the gas never leaves (percentile background).
        self.held: Optional[np.ndarray] = None
        #: The held pixels' background error relative to the gas's contrast
        #: there (:func:`held_background_error`; NaN when none is held).
        self.held_error = float("nan")
        #: By how much the held pixels' inpainting stood beyond their
        #: percentile's bound (C, h, w) [radiance, the gas's sign], where
        #: it was bounded (:func:`inpaint_held`); None without held pixels.
        self.held_clip: Optional[np.ndarray] = None
        # The background's static shape beyond a straight line across the
        # region (set by the run from its time-averaged frames).
        self.shape_correction: Optional[Dict[bool, np.ndarray]] = None
        #: The drifting background per channel (``"drifting"``), its drift's
        #: record, and the last frames' background images (ids, (B, C, h, w)).
        self._drifting: List[_engine.DriftingBackground] = []
        self.drift: Optional[dict] = None
        self._times = np.asarray(rec.time_s, float)
        self._drift_cache: Optional[tuple] = None
        self._window_frames = 0.0
        #: The drifting background's static layer's correction where the gas
        #: never leaves the pixels (C, h, w), added to every frame's.
        self._static_fix: Optional[np.ndarray] = None
        if cfg.background == "drifting":
            self._make_drifting(rec, frames, say)
        if cfg.background == "percentile":
            # Sign-aware: a plume warmer than the background raises radiance,
            # so its background is a low percentile; a colder one a high one.
            sl = roi.slices()
            # 200-399 frames spread over the run bound the memory, read into
            # one array (a list of frames and its copy held both).
            use = list(frames)[:: max(1, len(frames) // 200)]
            stacked = None
            for k, f in enumerate(use):
                img = rec.frame(f, quantity="radiance")[:, sl[0], sl[1]]
                if stacked is None:
                    stacked = np.empty((len(use),) + img.shape, img.dtype)
                stacked[k] = img
                if k % 50 == 0:
                    say(0.02 * k / len(use), "background (temporal percentile)")
            assert stacked is not None  # a run has frames
            noise = _noise(stacked)  # once, for the inpainting and its check
            self.percentile_img, self.held, self.held_clip = percentile_background(
                stacked,
                channel_sign,
                cfg.background_percentile,
                None
                if gas_temperature_K is None
                else np.array([ch.band_radiance(gas_temperature_K) for ch in rec.channels]),
                noise,
                source_xy=self._source_in_roi(),
                return_clip=True,
            )
            self.held_error = held_background_error(stacked, self.percentile_img, self.held, noise)
            mean = stacked.mean(axis=0)
            self._pedestal = np.array(
                [
                    max(
                        0.0,
                        float(np.median(self.channel_sign[c] * (mean[c] - self.percentile_img[c]))),
                    )
                    for c in range(mean.shape[0])
                ]
            )

    def noise_pedestal(self) -> Optional[np.ndarray]:
        """How far the percentile background stands from the gas-free mean
        towards the gas's side, per channel [radiance, >= 0 in the gas's
        sign; None for the other methods]: a temporal percentile of noisy
        frames is the background plus the noise's own percentile (about 1.5
        noise for the 5th of 45 frames). Measured, not modelled: the median
        over the region (mostly gas-free) of the time mean less the
        percentile, in the gas's sign, on the frames the percentile was taken
        from (a model of white NETD noise missed it by a tenth, which summed
        over a wide plume's samples was 10 points of a 10 g/h rate)."""
        return self._pedestal

    def _make_drifting(self, rec: Recording, frames: range, say) -> None:
        """The static and drifting layers of each channel over the region
        (:class:`qogi._engine.DriftingBackground`) from up to 200 frames
        spread over the run, with the drift measured on them
        (:func:`qogi._engine.measure_drift`, on the channels' sum in noise
        units); a drift not measured (its registrations did not converge) is
        taken as none: a running per-pixel percentile."""
        sl = self.roi.slices()
        use = list(frames)[:: max(1, len(frames) // 200)]
        stack = np.asarray(
            [rec.frame(f, quantity="radiance")[:, sl[0], sl[1]] for f in use], np.float32
        )
        times = self._times[use]
        say(0.01, "background (drift)")
        noise = np.maximum(_noise(stack), 1e-30)
        summed = np.ascontiguousarray((stack / noise[None, :, None, None]).sum(axis=1), np.float32)
        lags = _engine.DriftOptions()
        if len(use) < lags.difference_lag + lags.short_lag + 1:
            # Too few frames for a difference image to register against
            # another: no drift measured (a running per-pixel percentile).
            drift: Dict[str, Any] = {"measured": False, "pairs": 0, "converged": 0}
        else:
            drift = dict(_engine.measure_drift(summed, times, lags))
        if not drift["measured"]:
            drift["vx_px_s"] = drift["vy_px_s"] = 0.0
        self.drift = drift
        vx, vy = float(drift["vx_px_s"]), float(drift["vy_px_s"])
        opts = _engine.DriftingBackgroundOptions(
            percentile=float(self.cfg.background_percentile), num_threads=self.cfg.num_threads
        )
        # The frames one window of the drifting layer holds.
        span = float(times[-1] - times[0]) if len(times) > 1 else 0.0
        self._window_frames = len(use) * min(1.0, opts.window_s / span if span > 0 else 1.0)
        for c in range(stack.shape[1]):
            say(0.01 + 0.01 * c / stack.shape[1], "background (drifting layers)")
            self._drifting.append(
                _engine.DriftingBackground(
                    np.ascontiguousarray(stack[:, c]),
                    times,
                    vx,
                    vy,
                    1.0 if self.channel_sign[c] >= 0 else -1.0,
                    opts,
                )
            )
        # The static layer holds the gas where it never leaves the pixels
        # (the plume's base), as the percentile does: the frames less their
        # drifting layer are the static layer's own percentile stack, on which
        # its held pixels are found and inpainted (inpaint_held) and that
        # inpainting tried (held_background_error). The correction is added
        # to every frame's background (drifting_images).
        static = np.stack([d.static_layer for d in self._drifting])  # (C, h, w)
        residual = stack - (
            np.stack([np.stack([d.at(float(t)) for d in self._drifting]) for t in times])
            - static[None]
        )
        # Only the plume's base where the source is given: elsewhere the
        # clouds' edges the drifting layer did not follow widen the
        # percentile's tail too (a third of the clouds preset's frame), and
        # the static structure there is the scene's.
        fixed, held, self.held_clip = inpaint_held(
            residual,
            static,
            self.channel_sign,
            float(self.cfg.background_percentile),
            noise,
            source_xy=self._source_in_roi(),
            return_clip=True,
        )
        self.held = held
        self._static_fix = (fixed - static).astype(np.float32)
        self.held_error = held_background_error(residual, fixed, self.held, noise)

    def held_clip_at(self, xy: np.ndarray) -> Optional[np.ndarray]:
        """The held pixels' inpainting clip (:attr:`held_clip`) at samples
        ``xy`` (N, 2) [px, the image's]: (C, N), or None."""
        if self.held_clip is None or not np.any(self.held_clip):
            return None
        return _bilinear(self.held_clip, np.asarray(xy, float) - [self.roi.x0, self.roi.y0])

    def _source_in_roi(self) -> Optional[Tuple[float, float]]:
        """The given source (x, y) in the region's pixels, or None."""
        source = self.cfg.source
        return None if source is None else (source[0] - self.roi.x0, source[1] - self.roi.y0)

    def drifting_images(self, frame_ids: Sequence[int]) -> np.ndarray:
        """The drifting background over the region at the given frames:
        (B, C, h, w) float32 (the last call's kept: the block's proxy field
        and its surfaces ask for the same frames)."""
        ids = tuple(int(i) for i in frame_ids)
        if self._drift_cache is None or self._drift_cache[0] != ids:
            imgs = np.stack(
                [np.stack([d.at(float(self._times[i])) for d in self._drifting]) for i in ids]
            )
            if self._static_fix is not None:
                imgs += self._static_fix[None]
            self._drift_cache = (ids, imgs)
        return self._drift_cache[1]

    def drifting_relative(self, sample_frames: np.ndarray, sample_ids, samples) -> Dict[int, float]:
        """The drifting background's budget term per surface, relative to the
        surface's mean contrast on the sampled frames (as
        :func:`qogi.pipeline.background_choice.choose` sizes the others'): its scatter about
        the truth, about one noise (the engine's synthetic check:
        ``drifting_test``), plus the percentile's standard error over the
        window's frames."""
        sl = self.roi.slices()
        f = np.asarray(sample_frames, float)[:, :, sl[0], sl[1]]
        noise = np.maximum(_noise(f), 1e-30)
        bg = self.drifting_images(sample_ids).astype(float)
        origin = [self.roi.x0, self.roi.y0]
        rel: Dict[int, float] = {}
        delta = (1.0 + 1.3 / np.sqrt(max(2.0, self._window_frames))) * noise
        for j, (xy, _n, _dl, _t) in enumerate(samples):
            contrast = (_bilinear(f - bg, xy - origin) * self.channel_sign[None, :, None]).mean(
                axis=0
            )  # (C, N)
            rel[j] = _relative_to_contrast(delta, contrast)
        return rel

    def region_mean(self, frame: np.ndarray, region: Region) -> np.ndarray:
        """Mean of frames (..., C, H, W) over the region -> (..., C)."""
        r = region.clip(frame.shape[-1], frame.shape[-2])
        return frame[..., r.y0 : r.y1, r.x0 : r.x1].mean(axis=(-2, -1))

    def along(
        self,
        frame: np.ndarray,
        surface: Surface,
        xy: np.ndarray,
        t: np.ndarray,
        frame_ids: Optional[Sequence[int]] = None,
    ) -> np.ndarray:
        """Background radiance (..., C, N) at the surface samples xy of frames
        (..., C, H, W); ``frame_ids`` (B,), the frames' indices in the
        recording, for the drifting background (which changes with time)."""
        cfg = self.cfg
        n = len(xy)
        if cfg.background == "drifting":
            if frame_ids is None:
                raise ValueError("the drifting background needs the frames' indices (frame_ids)")
            imgs = self.drifting_images(frame_ids)
            return _bilinear(imgs, xy - [self.roi.x0, self.roi.y0]).reshape(frame.shape[:-2] + (n,))
        if isinstance(cfg.background, Region):
            return np.repeat(self.region_mean(frame, cfg.background)[..., None], n, axis=-1)
        if cfg.background == "percentile":
            assert self.percentile_img is not None  # made in __init__ for "percentile"
            return np.broadcast_to(
                _bilinear(self.percentile_img, xy - [self.roi.x0, self.roi.y0]),
                frame.shape[:-2] + (n,),
            )
        # Beside the surface: the mean radiance of short stretches just beyond
        # both ends, interpolated linearly along the surface.
        p = np.asarray(surface.points)
        ends = []
        for a, b in ((p[0], p[1]), (p[-1], p[-2])):
            d = (a - b) / np.hypot(*(a - b))
            pts = np.array([a + d * s for s in np.arange(2.0, 8.0, 1.0)])
            h, w = frame.shape[-2:]
            pts[:, 0] = np.clip(pts[:, 0], 0, w - 1)
            pts[:, 1] = np.clip(pts[:, 1], 0, h - 1)
            ends.append(_bilinear(frame, pts).mean(axis=-1))
        return ends[0][..., None] * (1 - t) + ends[1][..., None] * t

    def field(
        self,
        frame_roi: np.ndarray,
        horizontal: bool,
        channel: Optional[int] = None,
        frame_ids: Optional[Sequence[int]] = None,
    ) -> Optional[np.ndarray]:
        """Background over the analysis region: (C, h, w) for the frame's
        channels (C, h, w), or (h, w) for ``channel`` given one channel's
        (h, w); leading frame axes pass through (the drifting background
        needs the frames' indices ``frame_ids``, one per leading frame).
        None for a region background (uniform: the caller takes
        :meth:`region_mean`)."""
        cfg = self.cfg
        if cfg.background == "drifting":
            if frame_ids is None:
                raise ValueError("the drifting background needs the frames' indices (frame_ids)")
            imgs = self.drifting_images(frame_ids)
            out = imgs if channel is None else imgs[:, channel]
            return out.reshape(frame_roi.shape)
        if isinstance(cfg.background, Region):
            return None
        if cfg.background == "percentile":
            assert self.percentile_img is not None  # made in __init__ for "percentile"
            return self.percentile_img if channel is None else self.percentile_img[channel]
        # Per line along the plume, linear between 4-px strips at the region's
        # edges across it, plus the static shape of the background that a
        # straight line misses (a sky's elevation gradient across a
        # wind-blown plume, vignetting): the robust quadratic surface of the
        # time-averaged frames minus its own edge-to-edge interpolation.
        bg = self._edge_interpolation(frame_roi, horizontal)
        if self.shape_correction is not None:
            corr = self.shape_correction[horizontal]
            bg += corr if channel is None else corr[channel]
        return bg

    @staticmethod
    def _edge_interpolation(img: np.ndarray, horizontal: bool) -> np.ndarray:
        k = 4
        if horizontal:  # along x between the left and right strips
            left = img[..., :, :k].mean(axis=-1)
            right = img[..., :, -k:].mean(axis=-1)
            t = np.linspace(0, 1, img.shape[-1]).astype(img.dtype, copy=False)
            out = (right - left)[..., None] * t
            out += left[..., None]
            return out
        top = img[..., :k, :].mean(axis=-2)
        bottom = img[..., -k:, :].mean(axis=-2)
        t = np.linspace(0, 1, img.shape[-2])[:, None].astype(img.dtype, copy=False)
        out = (bottom - top)[..., None, :] * t
        out += top[..., None, :]
        return out

    def set_static_shape(self, mean_roi: np.ndarray) -> None:
        """From the time-averaged region (C, h, w): the background's static
        shape beyond the edge-to-edge interpolation, per orientation, used
        only where the smooth surface describes the gas-free pixels at least
        twice as well as that interpolation does (a plate or a linear
        gradient needs no correction, and gets none)."""

        def mad(r):
            return float(np.median(np.abs(r - np.median(r))))

        smooth = np.stack([_smooth_background(m) for m in mean_roi])
        self.shape_correction = {}
        for o in (True, False):
            lin = self._edge_interpolation(mean_roi, o)
            corr = smooth - self._edge_interpolation(smooth, o)
            use = np.zeros(len(mean_roi), bool)
            for c in range(len(mean_roi)):
                r_smooth = mean_roi[c] - smooth[c]
                free = np.abs(r_smooth - np.median(r_smooth)) <= 2.5 * 1.4826 * mad(r_smooth)
                use[c] = mad((mean_roi[c] - lin[c])[free]) > 2.0 * mad(r_smooth[free])
            self.shape_correction[o] = corr * use[:, None, None]
