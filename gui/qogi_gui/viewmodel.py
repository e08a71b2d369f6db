"""The viewer's state and actions, without any widget.

:class:`ViewModel` holds everything the window shows (the open recording, the
playback position and display settings, the drawn control surfaces and
background region, the analysis form, the running job and the result) and
every action a user can take (open, play, draw, configure, run, cancel,
export). The Dear PyGui layer (:mod:`qogi_gui.app`) only forwards input here
and draws what it finds, so all behaviour is tested without a screen.

Errors never escape an action: each one is turned into a readable
:class:`Message` (``vm.messages``; the newest is ``vm.last_message``) and the
action returns False.

The viewer uses only the public ``qogi`` API of docs/pipeline_api.md
(``open_recording``, ``Surface``, ``Region``, ``QuantifyConfig``,
``quantify``, ``Cancelled``, ``RecordingError``); the ``api`` argument lets
tests substitute an object with the same names.
"""

from __future__ import annotations

import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Dict, List, Optional, Sequence, Tuple

import numpy as np
from qogi.errors import UsageError

from . import display, results
from .export import (ExportError, check_writable, render_frame_rgb, report_text,
                     write_frame_png, write_pdf_report, write_plots, write_report)
from .jobs import CANCELLED, DONE, FAILED, Job
from .settings import BACKGROUNDS, AnalysisSettings, SettingsError
from .store import UserStore
from .surfaces import SURFACE_COLOURS, RegionDraft, SurfaceDraft

__all__ = ["ViewModel", "Message", "MODES", "SPEEDS"]

#: Interaction modes of the image: look (pan/zoom/read-out), draw a line (two
#: clicks), draw a polyline (clicks, right-click or Enter to finish), pick the
#: background region (two corners), pick the source, edit (drag vertices).
MODES = ("view", "line", "polyline", "region", "source", "edit")
#: Playback speeds (x real time).
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0)
MAX_MESSAGES = 200


@dataclass
class Message:
    level: str  # "info", "warning" or "error"
    text: str
    time_s: float


@dataclass
class DisplayState:
    """How the video is drawn."""

    channel: int = 0
    quantity: str = "radiance"          # or "radiometric_temperature"
    colormap: str = display.COLORMAPS[0]
    range_mode: str = "recording"       # "recording" (auto, fixed over the video), "frame", "fixed"
    fixed_min: float = 0.0
    fixed_max: float = 1.0
    show_overlay: bool = True           # column density over the video (when a result has maps)
    overlay_species: str = ""
    overlay_colormap: str = display.OVERLAY_COLORMAPS[0]
    show_vectors: bool = True           # velocity vectors (when a result has maps)


RANGE_MODES = ("recording", "frame", "fixed")


class ViewModel:
    """State and actions of the viewer.

    Parameters
    ----------
    api : module-like, optional
        Provides ``open_recording``, ``RecordingError``, ``Surface``,
        ``Region``, ``QuantifyConfig``, ``quantify`` and ``Cancelled`` as in
        docs/pipeline_api.md. Default: the ``qogi`` package.
    store : UserStore, optional
        Recent files; default the per-user store.
    demo_provider : callable(progress) -> path, optional
        Makes (or finds) the demo recording; default
        :func:`qogi_gui.demo.ensure_demo`.
    clock : callable() -> float, s
        Monotonic time for playback (tests pass a fake clock).
    """

    def __init__(self, api=None, store: Optional[UserStore] = None,
                 demo_provider: Optional[Callable] = None,
                 clock: Callable[[], float] = time.monotonic):
        if api is None:
            import qogi as api
        self.api = api
        self.store = store if store is not None else UserStore()
        if demo_provider is None:
            from .demo import ensure_demo as demo_provider
        self.demo_provider = demo_provider
        self.clock = clock
        self.messages: List[Message] = []
        if self.store.warning:
            self._warn(self.store.warning)

        self.recording = None
        self.recording_path: Optional[str] = None
        #: A camera file waiting for its scene facts (the form), or None.
        self.scene_request = None
        self.summary: Optional[dict] = None
        self.display = DisplayState()
        self.frame = 0
        self.playing = False
        self.speed = 1.0
        self._play_t = 0.0              # playback time since the first frame [s]
        self._last_tick: Optional[float] = None

        self.mode = "view"
        self.surfaces: List[SurfaceDraft] = []
        self.drawing: Optional[SurfaceDraft] = None
        self.selected: Optional[int] = None
        self.region: Optional[RegionDraft] = None
        self._corner: Optional[Tuple[float, float]] = None

        self.settings = AnalysisSettings()
        self.field_errors: Dict[str, str] = {}

        self.job: Optional[Job] = None
        self.job_kind = ""
        self._job_handled = True
        self._pending: tuple = ([], {}, False)
        self._opening = ""
        self.result = None
        self.result_partial = False
        self.result_surfaces: List[SurfaceDraft] = []
        self.result_settings: dict = {}
        self.result_has_maps = False
        self.result_stale = False
        #: Bumped when the corresponding state changes, so the window redraws only then.
        self.rev = {"recording": 0, "surfaces": 0, "result": 0, "settings": 0, "display": 0,
                    "scene_request": 0}

        self._frame_cache: Tuple[Optional[int], Optional[np.ndarray]] = (None, None)
        self._range_cache: Dict[tuple, Tuple[float, float]] = {}
        self._rgba: Optional[np.ndarray] = None
        self._scratch: Optional[np.ndarray] = None
        self._overlay: Optional[np.ndarray] = None
        self._overlay_vmax: Dict[str, float] = {}
        self._maps_cache: tuple = (None, None)
        self._map_frames: tuple = (None, [])
        self.last_range: Tuple[float, float] = (0.0, 1.0)

    # ================================================================= messages
    def _say(self, level: str, text: str) -> None:
        self.messages.append(Message(level, str(text), time.time()))
        del self.messages[:-MAX_MESSAGES]

    def _info(self, text: str) -> None:
        self._say("info", text)

    def _warn(self, text: str) -> None:
        self._say("warning", text)

    def _error(self, text: str) -> bool:
        self._say("error", text)
        return False

    @property
    def last_message(self) -> Optional[Message]:
        return self.messages[-1] if self.messages else None

    @property
    def busy(self) -> bool:
        """A background job (quantification or demo) is running."""
        return self.job is not None and self.job.running

    # ================================================================= recording
    def open(self, path, background: bool = False) -> bool:
        """Open a recording file (validated by ``qogi.open_recording``).

        With ``background`` the file is opened and checked in a worker thread
        (large files are scanned for NaN on open) and shown once
        :meth:`poll` sees it done; the window keeps drawing meanwhile."""
        if self.busy:
            return self._error(f"the {self.job.name} is still running: cancel it or wait before "
                               "opening another recording")
        p = os.path.abspath(os.path.expanduser(os.fspath(path))) if str(path).strip() else ""
        if not p:
            return self._error("no file chosen: pick a recording (.h5) or a camera file to open")
        facts = self._scene_facts(p)
        if facts is None:
            return False
        if background:
            self._opening = p
            self._start_job(Job("opening the recording",
                                lambda progress: self._open_file(p, facts)), "open")
            return True
        try:
            rec, warning = self._open_file(p, facts)
        except (ValueError, OSError) as e:
            return self._open_failed(p, e)
        return self._opened(rec, p, warning)

    # ----------------------------------------------------------------- camera files
    def _scene_facts(self, p: str):
        """Keyword arguments for opening ``p``: {} for a recording, the facts
        remembered for a camera file, or None when the form must ask for them
        (:attr:`scene_request` is then set)."""
        from qogi.io.open import file_kind, scene_needs

        if not os.path.isfile(p) or file_kind(p) not in ("flir", "telops"):
            return {}
        stored = self.store.scene_for(p)
        try:
            needs = scene_needs(p)
        except (ValueError, OSError) as e:
            self._open_failed(p, e)
            return None
        if stored and all(k in stored for k in needs["needs"]):
            return dict(stored)
        self._ask_scene(p, needs, stored or {})
        return None

    def _ask_scene(self, p: str, needs: dict, values: dict, error: str = "") -> None:
        from .scene_form import FIELDS, SceneRequest

        self.scene_request = SceneRequest(
            path=p, kind=needs["kind"], needs=list(needs["needs"]), holds=dict(needs["holds"]),
            defaults=list(needs["defaults"]),
            values={k: "" if values.get(k) is None else str(values.get(k)) for k in FIELDS},
            error=error)
        self.rev["scene_request"] += 1
        missing = ", ".join(FIELDS[k][0] for k in needs["needs"])
        if error:
            self._error(error)
        else:
            self._info(f"{os.path.basename(p)} is a camera file: give the scene facts it does not "
                       f"hold ({missing}) in the form")

    def submit_scene(self, values: dict) -> bool:
        """Open the pending camera file with the form's ``values`` (text per
        field); remember them for the file when it opens."""
        from .scene_form import parse_facts

        req = self.scene_request
        if req is None:
            return self._error("no camera file is waiting for scene facts")
        req.values.update({k: str(v) for k, v in values.items()})
        facts, errors = parse_facts(req.values, req.needs)
        req.errors = errors
        if errors:
            req.error = "; ".join(errors.values())
            self.rev["scene_request"] += 1
            return self._error(f"fix the scene facts first: {req.error}")
        try:
            rec, warning = self._open_file(req.path, facts)
        except (ValueError, OSError) as e:
            req.error = str(e)
            self.rev["scene_request"] += 1
            return self._error(f"could not open {os.path.basename(req.path)}: {e}")
        self.scene_request = None
        self.rev["scene_request"] += 1
        self.store.set_scene(req.path, facts)
        return self._opened(rec, req.path, warning)

    def cancel_scene(self) -> None:
        """Close the scene form without opening the file."""
        self.scene_request = None
        self.rev["scene_request"] += 1

    def _open_file(self, p: str, facts: Optional[dict] = None):
        """(recording, warning) of the file ``p``; NaN pixels become invalid pixels."""
        if facts:
            return self.api.open_recording(p, **facts), ""
        try:
            return self.api.open_recording(p), ""
        except self.api.RecordingError as e:
            if "non-finite" not in str(e) or getattr(e, "location", "") != "/frames":
                raise
        rec = self.api.open_recording(p, nonfinite="invalid")
        return rec, (f"{rec.n_invalid} non-finite pixel values in {p} are treated as invalid "
                     "pixels (shown transparent, not quantified)")

    def _opened(self, rec, p: str, warning: str) -> bool:
        self._set_recording(rec, p)
        if warning:
            self._warn(warning)
        for d in getattr(rec, "warnings", None) or ():
            self._warn(str(d))
        self.store.add_recent(p)
        if self.store.warning:
            self._warn(self.store.warning)
        self._info(f"opened {p}: {rec.n_frames} frames x {rec.n_channels} channel(s), "
                   f"{rec.width}x{rec.height} px, {rec.camera.frame_rate_hz:g} Hz")
        return True

    def _open_failed(self, path: str, e: Exception) -> bool:
        if not os.path.exists(path):
            self.store.remove_recent(path)
        elif isinstance(e, UsageError) and self.scene_request is None:
            # A camera file whose remembered facts no longer fit (e.g. a camera
            # whose band is not the file's): ask again, saying why.
            from qogi.io.open import scene_needs
            try:
                self._ask_scene(path, scene_needs(path), self.store.scene_for(path) or {},
                                error=f"could not open {os.path.basename(path)}: {e}")
                return False
            except (ValueError, OSError):
                pass
        return self._error(f"could not open the recording: {e}")

    def set_recording(self, recording, path: str = "") -> None:
        """Show an already opened ``qogi.Recording`` (scripts, tests)."""
        self._set_recording(recording, path or getattr(recording, "path", ""))

    def _set_recording(self, rec, path: str) -> None:
        if self.recording is not None and self.recording is not rec:
            try:
                self.recording.close()
            except Exception:  # closing a file we are done with must not stop the new one
                pass
        self.recording, self.recording_path = rec, path
        self.summary = rec.summary()
        self.display.channel = 0
        self.display.quantity = rec.quantity
        self.frame, self._play_t, self.playing = 0, 0.0, False
        self.surfaces, self.drawing, self.selected, self.region = [], None, None, None
        self.mode = "view"
        self.settings = AnalysisSettings.for_recording(rec)
        self.field_errors = {}
        self.result, self.result_partial, self.result_stale = None, False, False
        self.result_surfaces, self.result_settings = [], {}
        self._frame_cache = (None, None)
        self._range_cache.clear()
        self._overlay_vmax.clear()
        h, w = rec.height, rec.width
        self._rgba = np.zeros((h, w, 4), np.float32)
        self._scratch = np.empty((h, w), np.float32)
        self._overlay = np.zeros((h, w, 4), np.float32)
        lo, hi = self.auto_range()
        self.display.fixed_min, self.display.fixed_max = lo, hi
        for k in self.rev:
            self.rev[k] += 1

    def open_demo(self) -> bool:
        """Open the demo scene: synthesised once (in the background, with
        progress) and then reused from the user's cache."""
        if self.busy:
            return self._error(f"the {self.job.name} is still running: cancel it or wait")
        self._start_job(Job("demo scene", self.demo_provider), "demo")
        self._info("preparing the demo scene...")
        return True

    def metadata_rows(self) -> List[Tuple[str, str]]:
        """(label, value) pairs describing the open recording."""
        s = self.summary
        if not s:
            return []
        cam, fr, sc = s["camera"], s["frames"], s["scene"]
        rows = [("file", str(s["path"])),
                ("camera", str(cam["name"])),
                ("pixel field of view", f"{cam['ifov_rad'] * 1e3:.4g} mrad"),
                ("frame rate", f"{cam['frame_rate_hz']:.4g} Hz"),
                ("NETD", f"{cam['netd_K'] * 1e3:.3g} mK" if cam.get("netd_K") else "-"),
                ("frames", f"{fr['T']} x {fr['C']} channel(s) x {fr['W']}x{fr['H']} px"),
                ("duration", f"{fr['duration_s']:.3f} s"),
                ("stored quantity", f"{fr['quantity']} [{fr['unit']}]")]
        for ch in s["channels"]:
            lo, hi = ch["half_max_cm1"]
            rows.append((f"channel {ch['index']}",
                         f"{ch['name']}: {1e4 / hi:.3f}-{1e4 / lo:.3f} um (half max), "
                         f"centroid {ch['centroid_um']:.3f} um"))
        rows += [("distance", f"{sc['distance_m']:g} m"),
                 ("ambient temperature", f"{sc['ambient_temperature_K']:.2f} K"),
                 ("pressure", f"{sc['pressure_Pa']:.0f} Pa")]
        for key, label, unit in (("wind_speed_m_s", "wind speed", "m/s"),
                                 ("gas_temperature_K", "gas temperature", "K"),
                                 ("background_temperature_K", "background temperature", "K")):
            if sc.get(key) is not None:
                rows.append((label, f"{sc[key]:g} {unit}"))
        if sc.get("species"):
            rows.append(("species", ", ".join(sc["species"])))
        if fr.get("n_invalid"):
            rows.append(("invalid pixel values", str(fr["n_invalid"])))
        truth = s.get("truth")
        if truth:
            for sp, v in truth["emission_rate_kg_h"].items():
                rows.append((f"true {sp} rate", f"{v:.4g} kg/h"))
        return rows

    # ================================================================= playback
    @property
    def n_frames(self) -> int:
        return self.recording.n_frames if self.recording is not None else 0

    @property
    def frame_time_s(self) -> float:
        if self.recording is None:
            return 0.0
        return float(self.recording.time_s[self.frame] - self.recording.time_s[0])

    def seek(self, frame: int) -> None:
        """Show frame ``frame`` (clamped to the recording)."""
        if self.recording is None:
            return
        self.frame = int(min(max(int(frame), 0), self.n_frames - 1))
        self._play_t = self.frame_time_s

    def step(self, n: int = 1) -> None:
        self.playing = False
        self.seek(self.frame + n)

    def play(self, on: Optional[bool] = None) -> None:
        """Start or stop playback (toggle when ``on`` is None)."""
        if self.recording is None:
            return
        self.playing = (not self.playing) if on is None else bool(on)
        self._last_tick = self.clock()
        if self.playing and self.frame >= self.n_frames - 1:
            self.seek(0)

    def set_speed(self, speed: float) -> bool:
        try:
            v = float(speed)
        except (TypeError, ValueError):
            return self._error(f"playback speed must be a number; got {speed!r}")
        if not 0 < v <= 100:
            return self._error(f"playback speed must be in (0, 100] x real time; got {v:g}")
        self.speed = v
        return True

    def tick(self) -> bool:
        """Advance playback to the clock; True if the shown frame changed.
        Frames follow the recording's own times (``time_s``), looping at the end."""
        now = self.clock()
        last, self._last_tick = self._last_tick, now
        if not self.playing or self.recording is None or last is None:
            return False
        t = self.recording.time_s
        self._play_t += (now - last) * self.speed
        period = float(t[-1] - t[0]) + 1.0 / float(self.recording.camera.frame_rate_hz)
        if self._play_t >= period:
            self._play_t %= period
        i = int(np.searchsorted(t - t[0], self._play_t, side="right")) - 1
        i = min(max(i, 0), self.n_frames - 1)
        changed = i != self.frame
        self.frame = i
        return changed

    # ================================================================= display
    def set_display(self, **changes) -> bool:
        """Change display settings (fields of :class:`DisplayState`), checked."""
        d = self.display
        for k, v in changes.items():
            if not hasattr(d, k):
                return self._error(f"unknown display setting {k!r}")
            if k == "channel" and self.recording is not None and not \
                    0 <= int(v) < self.recording.n_channels:
                return self._error(f"channel must be 0..{self.recording.n_channels - 1}; got {v}")
            if k == "quantity" and v not in display.QUANTITY_LABELS:
                return self._error(f"quantity must be one of {', '.join(display.QUANTITY_LABELS)}")
            if k == "colormap" and v not in display.COLORMAPS:
                return self._error(f"colour map must be one of {', '.join(display.COLORMAPS)}")
            if k == "overlay_colormap" and v not in display.OVERLAY_COLORMAPS:
                return self._error("overlay colour map must be one of "
                                   f"{', '.join(display.OVERLAY_COLORMAPS)}")
            if k == "range_mode" and v not in RANGE_MODES:
                return self._error(f"range must be one of {', '.join(RANGE_MODES)}")
        fixed = {k: changes[k] for k in ("fixed_min", "fixed_max") if k in changes}
        if fixed:
            try:
                lo = float(fixed.get("fixed_min", d.fixed_min))
                hi = float(fixed.get("fixed_max", d.fixed_max))
            except (TypeError, ValueError):
                return self._error("the fixed range needs two numbers")
            if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
                return self._error(f"the fixed range needs min < max; got {lo:g} .. {hi:g}")
            changes["fixed_min"], changes["fixed_max"] = lo, hi
        if "channel" in changes:
            changes["channel"] = int(changes["channel"])
        for k, v in changes.items():
            setattr(d, k, v)
        if ("channel" in changes or "quantity" in changes) and self.recording is not None \
                and "fixed_min" not in changes:
            # A fixed range in other units would be meaningless: restart it from auto.
            d.fixed_min, d.fixed_max = self.auto_range()
        self.rev["display"] += 1
        return True

    @property
    def unit(self) -> str:
        return "W/(m2 sr)" if self.display.quantity == "radiance" else "K"

    def current_frame(self) -> np.ndarray:
        """All channels of the shown frame, stored quantity, (C, H, W) float32 (cached)."""
        i, a = self._frame_cache
        if i != self.frame or a is None:
            a = self.recording.frames(self.frame, self.frame + 1)[0]
            self._frame_cache = (self.frame, a)
        return a

    def channel_image(self) -> np.ndarray:
        """The shown channel of the shown frame in the displayed quantity, (H, W)."""
        a = self.current_frame()[self.display.channel]
        q = self.display.quantity
        if q == self.recording.quantity:
            return a
        from qogi.radiometry import band_table

        table = band_table(self.recording.channels[self.display.channel])
        return table.radiance(a) if q == "radiance" else table.temperature(a)

    def auto_range(self) -> Tuple[float, float]:
        """Robust range of the shown channel and quantity over the recording (cached)."""
        key = (self.display.channel, self.display.quantity)
        if key not in self._range_cache:
            self._range_cache[key] = display.recording_range(self.recording, *key)
        return self._range_cache[key]

    def display_range(self, image: Optional[np.ndarray] = None) -> Tuple[float, float]:
        d = self.display
        if d.range_mode == "fixed":
            return d.fixed_min, d.fixed_max
        if d.range_mode == "frame":
            return display.robust_range(self.channel_image() if image is None else image)
        return self.auto_range()

    def render(self) -> Optional[np.ndarray]:
        """The shown frame as RGBA float32 (H, W, 4) in a reused buffer (None
        without a recording). Also sets :attr:`last_range`."""
        if self.recording is None:
            return None
        img = self.channel_image()
        lo, hi = self.display_range(img)
        self.last_range = (lo, hi)
        return display.colorize(img, lo, hi, display.colormap_lut(self.display.colormap),
                                out=self._rgba, scratch=self._scratch)

    # ----------------------------------------------------------------- result on the video
    def frame_maps(self) -> Optional[dict]:
        """The result's per-pixel maps of the shown frame (full-frame arrays), or None."""
        if self.result is None:
            return None
        key = (self.rev["result"], self.frame)
        if self._maps_cache[0] != key:
            self._maps_cache = (key, results.frame_maps(
                self.result, self.frame, (self.recording.height, self.recording.width)))
        return self._maps_cache[1]

    def _overlay_species(self) -> Optional[str]:
        if self.result is None:
            return None
        names = self.result_species()
        if not names:
            return None
        return self.display.overlay_species if self.display.overlay_species in names else names[0]

    def result_species(self) -> List[str]:
        if self.result is None:
            return []
        seen = []
        for sr in self.result.surfaces:
            for sp in sr.species:
                if sp not in seen:
                    seen.append(sp)
        return seen

    def map_frames(self) -> List[int]:
        """Frames for which the result kept per-pixel maps (the pipeline may keep
        them for a subset of the frames only)."""
        if self.result is None:
            return []
        if self._map_frames[0] != self.rev["result"]:
            kept = results.map_frame_keys(self.result)
            self._map_frames = (self.rev["result"], sorted(kept))
        return self._map_frames[1]

    def seek_map_frame(self, direction: int = 1) -> bool:
        """Show the next (direction > 0) or previous frame that has maps."""
        frames = self.map_frames()
        if not frames:
            return self._error("the result holds no per-pixel maps: run with 'keep per-pixel "
                               "maps' ticked")
        later = [f for f in frames if f > self.frame] if direction > 0 else \
            [f for f in frames if f < self.frame]
        target = (later[0] if direction > 0 else later[-1]) if later else \
            (frames[0] if direction > 0 else frames[-1])
        self.playing = False
        self.seek(target)
        return True

    def overlay_vmax(self) -> float:
        """Top of the column-density colour scale [kg/m2] (fixed per result and species)."""
        sp = self._overlay_species()
        if sp is None:
            return 0.0
        if sp not in self._overlay_vmax:
            kept = self.map_frames()
            frames = [kept[int(i)] for i in np.linspace(0, len(kept) - 1,
                                                        min(8, len(kept))).round()] if kept else []
            self._overlay_vmax[sp] = results.overlay_scale(
                self.result, sp, frames, (self.recording.height, self.recording.width))
        return self._overlay_vmax[sp]

    def render_overlay(self) -> Optional[np.ndarray]:
        """Column density of the shown frame as RGBA (H, W, 4), transparent where
        there is no gas; None when hidden or not available."""
        if not self.display.show_overlay or self.result is None:
            return None
        maps = self.frame_maps()
        sp = self._overlay_species()
        if not maps or sp is None:
            return None
        col = maps.get("column_density_kg_m2", {}).get(sp)
        vmax = self.overlay_vmax()
        if col is None or not vmax > 0:
            return None
        return display.colorize_overlay(col, vmax,
                                        display.colormap_lut(self.display.overlay_colormap),
                                        out=self._overlay)

    def vectors(self, spacing: int = 12) -> Tuple[np.ndarray, np.ndarray, float]:
        """Velocity arrows (tails, heads, scale) of the shown frame where the
        overlay species has gas; empty when hidden or not available."""
        empty = (np.zeros((0, 2)), np.zeros((0, 2)), 0.0)
        if not self.display.show_vectors or self.result is None:
            return empty
        maps = self.frame_maps()
        if not maps or "velocity_px_per_frame" not in maps:
            return empty
        u, v = maps["velocity_px_per_frame"]
        sp = self._overlay_species()
        col = maps.get("column_density_kg_m2", {}).get(sp) if sp else None
        vmax = self.overlay_vmax()
        return results.vector_field(u, v, weight=col, spacing=spacing,
                                    min_weight=0.05 * vmax if col is not None else 0.0)

    def px_per_frame_to_m_s(self) -> float:
        """Speed [m/s] of 1 px/frame at the scene distance (pixel size x frame rate)."""
        if self.recording is None:
            return math.nan
        return (float(self.recording.scene.distance_m) * float(self.recording.camera.ifov_rad)
                * float(self.recording.camera.frame_rate_hz))

    def readout(self, x: float, y: float) -> Optional[dict]:
        """What is under the cursor at pixel coordinates (x, y): per channel the
        band radiance [W/(m2 sr)] and radiometric temperature [K]; with a
        result, column density and velocity. None outside the image."""
        if self.recording is None or not (math.isfinite(x) and math.isfinite(y)):
            return None
        ix, iy = int(math.floor(x + 0.5)), int(math.floor(y + 0.5))
        if not (0 <= ix < self.recording.width and 0 <= iy < self.recording.height):
            return None
        from qogi.radiometry import band_table

        frame = self.current_frame()
        out = {"x": ix, "y": iy, "frame": self.frame, "time_s": self.frame_time_s,
               "channels": []}
        for k, ch in enumerate(self.recording.channels):
            v = np.float64(frame[k, iy, ix])
            if not np.isfinite(v):
                out["channels"].append({"name": ch.name, "radiance": math.nan,
                                        "temperature_K": math.nan})
                continue
            tab = band_table(ch)
            if self.recording.quantity == "radiance":
                rad, tem = float(v), float(tab.temperature(np.array([v]))[0])
            else:
                rad, tem = float(tab.radiance(np.array([v]))[0]), float(v)
            out["channels"].append({"name": ch.name, "radiance": rad, "temperature_K": tem})
        maps = self.frame_maps()
        if maps:
            cols = maps.get("column_density_kg_m2", {})
            out["column_density_kg_m2"] = {sp: float(np.asarray(c)[iy, ix])
                                           for sp, c in cols.items()}
            if "velocity_px_per_frame" in maps:
                u, v = maps["velocity_px_per_frame"]
                out["velocity_px_per_frame"] = (float(np.asarray(u)[iy, ix]),
                                                float(np.asarray(v)[iy, ix]))
                out["velocity_m_s"] = tuple(c * self.px_per_frame_to_m_s()
                                            for c in out["velocity_px_per_frame"])
            if "status" in maps:
                out["status"] = maps["status"][iy, ix].item() if hasattr(
                    maps["status"][iy, ix], "item") else maps["status"][iy, ix]
        return out

    # ================================================================= drawing
    def set_mode(self, mode: str) -> bool:
        """Switch what a click on the image does (see :data:`MODES`)."""
        if mode not in MODES:
            return self._error(f"unknown mode {mode!r}; modes: {', '.join(MODES)}")
        if self.drawing is not None and mode != self.mode:
            self.finish_drawing(quiet=True)
        self._corner = None
        self.mode = mode
        self.rev["surfaces"] += 1
        return True

    def _inside(self, x: float, y: float) -> bool:
        """On the image as displayed (pixel squares included)."""
        r = self.recording
        return r is not None and -0.5 <= x <= r.width - 0.5 and -0.5 <= y <= r.height - 0.5

    def _snap(self, x: float, y: float) -> Tuple[float, float]:
        """A point on the image kept within the outermost pixel centres
        ([0, W-1] x [0, H-1]), where the pipeline can sample it."""
        r = self.recording
        return (min(max(float(x), 0.0), r.width - 1.0), min(max(float(y), 0.0), r.height - 1.0))

    def click(self, x: float, y: float, button: str = "left", tolerance_px: float = 4.0) -> bool:
        """A click on the image at pixel coordinates (x, y), by mode: add a
        surface point; finish a polyline (right button); set a region corner;
        set the source; select the surface nearest the click."""
        if self.recording is None:
            return self._error("open a recording (or the demo) before drawing")
        if button == "right":
            if self.mode == "polyline" and self.drawing is not None:
                return self.finish_drawing()
            return False
        if not self._inside(x, y):
            return self._error(f"({x:.1f}, {y:.1f}) is outside the image: click on the frame")
        x, y = self._snap(x, y)
        if self.mode in ("line", "polyline"):
            if self.drawing is None:
                n = len(self.surfaces)
                self.drawing = SurfaceDraft(self._new_name(),
                                            colour=SURFACE_COLOURS[n % len(SURFACE_COLOURS)])
            if self.drawing.points and math.dist(self.drawing.points[-1], (x, y)) < 1e-6:
                return self._error("that point repeats the previous one: click somewhere else")
            self.drawing.points.append((float(x), float(y)))
            self.rev["surfaces"] += 1
            if self.mode == "line" and len(self.drawing.points) == 2:
                return self.finish_drawing()
            return True
        if self.mode == "region":
            if self._corner is None:
                self._corner = (float(x), float(y))
                self.rev["surfaces"] += 1
                return True
            region = RegionDraft.from_corners(self._corner, (x, y), self.recording.width,
                                              self.recording.height)
            self._corner = None
            if region.n_pixels < 1:
                return self._error("the region holds no pixel centre: drag a larger rectangle")
            return self.set_region(region)
        if self.mode == "source":
            self.settings.use_source = True
            self.settings.source_x, self.settings.source_y = f"{x:.1f}", f"{y:.1f}"
            self.rev["settings"] += 1
            self._info(f"source set at ({x:.1f}, {y:.1f}) px: surfaces are oriented so that "
                       "flow away from it counts positive")
            return True
        # view / edit: select the nearest surface
        best = None
        for i, s in enumerate(self.surfaces):
            d = s.distance_to((x, y))
            if d <= tolerance_px and (best is None or d < best[1]):
                best = (i, d)
        self.selected = best[0] if best else None
        self.rev["surfaces"] += 1
        return best is not None

    def _new_name(self) -> str:
        names = {s.name for s in self.surfaces}
        k = len(self.surfaces) + 1
        while f"S{k}" in names:
            k += 1
        return f"S{k}"

    @property
    def region_corner(self) -> Optional[Tuple[float, float]]:
        """The first corner of a region being picked, or None."""
        return self._corner

    def finish_drawing(self, quiet: bool = False) -> bool:
        """Complete the surface being drawn (>= 2 distinct points), or drop it."""
        d, self.drawing = self.drawing, None
        self.rev["surfaces"] += 1
        if d is None:
            return False
        if not d.complete:
            if not quiet:
                self._error("a surface needs at least two distinct points: it was not kept")
            return False
        self.surfaces.append(d)
        self.selected = len(self.surfaces) - 1
        self._changed_inputs()
        self._info(f"surface {d.name} drawn ({len(d.points)} points); the arrow shows the "
                   "direction counted positive")
        return True

    def cancel_drawing(self) -> None:
        self.drawing, self._corner = None, None
        self.rev["surfaces"] += 1

    def undo_point(self) -> None:
        """Remove the last point of the surface being drawn."""
        if self.drawing is not None and self.drawing.points:
            self.drawing.points.pop()
            if not self.drawing.points:
                self.drawing = None
            self.rev["surfaces"] += 1

    def add_surface(self, points, name: str = "") -> bool:
        """Add a surface from typed points [(x, y), ...] (all inside the image)."""
        if self.recording is None:
            return self._error("open a recording before adding surfaces")
        try:
            pts = [(float(x), float(y)) for x, y in points]
        except (TypeError, ValueError):
            return self._error(f"surface points must be (x, y) pairs of numbers; got {points!r}")
        r = self.recording
        bad = [p for p in pts if not (0 <= p[0] <= r.width - 1 and 0 <= p[1] <= r.height - 1)]
        if bad:
            return self._error(f"surface point {bad[0]} is outside the image: x must be in "
                               f"[0, {r.width - 1}] and y in [0, {r.height - 1}] px")
        n = len(self.surfaces)
        d = SurfaceDraft(name.strip() or self._new_name(), pts,
                         SURFACE_COLOURS[n % len(SURFACE_COLOURS)])
        if not d.complete:
            return self._error("a surface needs at least two distinct points")
        if any(s.name == d.name for s in self.surfaces):
            return self._error(f"a surface named {d.name!r} exists already")
        self.surfaces.append(d)
        self.selected = n
        self.rev["surfaces"] += 1
        self._changed_inputs()
        return True

    def auto_surfaces(self, distances_px: Sequence[float] = (30.0, 60.0, 90.0)) -> bool:
        """Detect the plume (qogi.plume_image of the first 50 frames) and add
        straight surfaces across it at these distances from its source
        (qogi.auto_surfaces); without a source set, the detected one is set
        too (it orients the surfaces and gives the velocimetry its flux level)."""
        import qogi

        if self.recording is None:
            return self._error("open a recording before placing surfaces")
        try:
            dists = [float(d) for d in distances_px]
        except (TypeError, ValueError):
            return self._error(f"distances must be numbers of pixels; got {distances_px!r}")
        if not dists or any(not (d > 0) for d in dists):
            return self._error("give one or more distances > 0 px, e.g. 30, 60, 90")
        source = None
        if self.settings.use_source:
            try:
                source = (float(self.settings.source_x), float(self.settings.source_y))
            except ValueError:
                source = None
        try:
            found, src = qogi.auto_surfaces(qogi.plume_image(self.recording), dists,
                                            source=source, return_source=True)
        except ValueError as e:
            return self._error(f"automatic surfaces: {e}")
        r = self.recording
        added = 0
        for surf in found:
            pts = [(min(max(x, 0.0), r.width - 1.0), min(max(y, 0.0), r.height - 1.0))
                   for x, y in surf.points]
            name = surf.name
            k = 2
            while any(s.name == name for s in self.surfaces):
                name = f"{surf.name} {k}"
                k += 1
            if self.add_surface(pts, name):
                added += 1
        if source is None:
            self.settings.use_source = True
            self.settings.source_x, self.settings.source_y = f"{src[0]:.1f}", f"{src[1]:.1f}"
            self.rev["settings"] += 1
            self.rev["surfaces"] += 1
        self._info(f"{added} surface(s) placed across the plume at "
                   f"{', '.join(f'{d:g}' for d in dists)} px from the source at "
                   f"({src[0]:.1f}, {src[1]:.1f}) px")
        return added > 0

    def _surface(self, index: int) -> Optional[SurfaceDraft]:
        if not 0 <= index < len(self.surfaces):
            self._error(f"there is no surface {index + 1} (there are {len(self.surfaces)})")
            return None
        return self.surfaces[index]

    def move_vertex(self, index: int, vertex: int, x: float, y: float) -> bool:
        """Move one point of a surface (edit mode); kept inside the image."""
        s = self._surface(index)
        if s is None:
            return False
        if not 0 <= vertex < len(s.points):
            return self._error(f"surface {s.name} has no point {vertex}")
        x, y = self._snap(x, y)
        others = s.points[:vertex] + s.points[vertex + 1:]
        if any(math.dist(p, (x, y)) < 1e-6 for p in others):
            return self._error("two points of a surface cannot coincide")
        s.points[vertex] = (x, y)
        self.rev["surfaces"] += 1
        self._changed_inputs()
        return True

    def delete_surface(self, index: int) -> bool:
        s = self._surface(index)
        if s is None:
            return False
        del self.surfaces[index]
        self.selected = None
        self.rev["surfaces"] += 1
        self._changed_inputs()
        self._info(f"surface {s.name} deleted")
        return True

    def reverse_surface(self, index: int) -> bool:
        """Walk a surface the other way: flips the direction counted positive."""
        s = self._surface(index)
        if s is None:
            return False
        self.surfaces[index] = s.reversed()
        self.rev["surfaces"] += 1
        self._changed_inputs()
        return True

    def rename_surface(self, index: int, name: str) -> bool:
        s = self._surface(index)
        if s is None:
            return False
        name = str(name).strip()
        if not name:
            return self._error("a surface needs a name")
        if any(o.name == name for i, o in enumerate(self.surfaces) if i != index):
            return self._error(f"a surface named {name!r} exists already")
        s.name = name
        self.rev["surfaces"] += 1
        self._changed_inputs()
        return True

    def set_region(self, region: Optional[RegionDraft]) -> bool:
        """Set (or clear with None) the background region; choosing one
        switches the background setting to it."""
        if region is not None:
            r = self.recording
            if r is None:
                return self._error("open a recording before picking a region")
            if not (0 <= region.x0 < region.x1 <= r.width and 0 <= region.y0 < region.y1
                    <= r.height):
                return self._error(f"region {region.as_tuple()} is not a rectangle inside the "
                                   f"{r.width}x{r.height} image")
            self.settings.background = "region"
            self._info(f"background region x {region.x0}..{region.x1 - 1}, y {region.y0}.."
                       f"{region.y1 - 1} ({region.n_pixels} pixels)")
        elif self.settings.background == "region":
            self.settings.background = BACKGROUNDS[0]
        self.region = region
        self.rev["surfaces"] += 1
        self.rev["settings"] += 1
        self._changed_inputs()
        return True

    def _changed_inputs(self) -> None:
        if self.result is not None:
            self.result_stale = True

    # ================================================================= settings
    def update_settings(self, **fields) -> Dict[str, str]:
        """Set form fields (names of :class:`AnalysisSettings`), as typed by the
        user, and return the per-field messages of the whole form. (The form's
        widgets already show these values, so ``rev["settings"]`` is not bumped;
        it is for changes made elsewhere, e.g. a source picked on the image.)"""
        for k, v in fields.items():
            if not hasattr(self.settings, k):
                self._error(f"unknown setting {k!r}")
                continue
            setattr(self.settings, k, v)
            if k in ("use_source", "source_x", "source_y"):
                self.rev["surfaces"] += 1  # the source marker on the image
        self._changed_inputs()
        return self.validate_settings()

    def validate_settings(self) -> Dict[str, str]:
        self.field_errors = self.settings.validate(self.recording, self.region)
        return self.field_errors

    # ================================================================= run
    def start_run(self) -> bool:
        """Check everything, then run ``qogi.quantify`` in the background."""
        if self.recording is None:
            return self._error("open a recording (or the demo) first")
        if self.busy:
            return self._error(f"the {self.job.name} is already running")
        if self.drawing is not None:
            self.finish_drawing()
        if not self.surfaces:
            return self._error("draw at least one control surface across the plume "
                               "(Surfaces: line or polyline) before running")
        try:
            kwargs = self.settings.config_kwargs(self.api, self.recording, self.region)
            config = self.settings.build_config(self.api, self.recording, self.region)
        except SettingsError as e:
            self.field_errors = {k: "" for k in self.field_errors} | e.errors
            return self._error(f"fix the analysis settings first: {e}")
        try:
            surfaces = [self.api.Surface(list(s.points), name=s.name) for s in self.surfaces]
        except (ValueError, TypeError) as e:
            return self._error(f"a control surface is not valid: {e}")
        self.field_errors = {}
        rec, keep = self.recording, bool(self.settings.keep_maps)
        api = self.api

        def work(progress):
            return api.quantify(rec, surfaces, config, progress=progress, keep_maps=keep)

        self._pending = ([SurfaceDraft(s.name, list(s.points), s.colour) for s in self.surfaces],
                         kwargs, keep)
        self._start_job(Job("quantification", work, cancelled_types=(self.api.Cancelled,)),
                        "quantify")
        self._info(f"quantifying {', '.join(kwargs['species'])} through "
                   f"{len(surfaces)} surface(s)...")
        return True

    def _start_job(self, job: Job, kind: str) -> None:
        self.job, self.job_kind, self._job_handled = job, kind, False
        job.start()

    def cancel_run(self) -> bool:
        """Ask the running job to stop; the window keeps running meanwhile."""
        if not self.busy:
            return self._error("nothing is running")
        self.job.cancel()
        self._info(f"cancelling the {self.job.name}...")
        return True

    def progress(self) -> Optional[dict]:
        """State of the current or last job (state, fraction, message, elapsed_s)."""
        return self.job.snapshot() if self.job is not None else None

    def poll(self) -> bool:
        """Take in a finished job's outcome; True when something finished."""
        job = self.job
        if job is None or job.running or self._job_handled:
            return False
        self._job_handled = True
        snap = job.snapshot()
        if self.job_kind == "open":
            if snap["state"] == DONE:
                self._opened(job.value[0], self._opening, job.value[1])
            elif isinstance(job.error, (ValueError, OSError)):
                self._open_failed(self._opening, job.error)
            else:
                self._report_failure("opening the recording", job)
            return True
        if self.job_kind == "demo":
            if snap["state"] == DONE:
                self.open(job.value)
            elif snap["state"] == CANCELLED:
                self._warn("the demo scene was not made (cancelled)")
            else:
                self._report_failure("making the demo scene", job)
            return True
        surfaces, kwargs, keep = self._pending
        if snap["state"] == DONE:
            self._take_result(job.value, surfaces, kwargs, keep, partial=False)
            self._info(f"quantification finished in {snap['elapsed_s']:.1f} s")
        elif snap["state"] == CANCELLED:
            if job.partial is not None:
                self._take_result(job.partial, surfaces, kwargs, keep, partial=True)
                n = max((r.n_frames for r in results.rate_rows(job.partial)), default=0)
                self._warn(f"quantification cancelled; showing the partial result of the "
                           f"{n} frame(s) finished")
            else:
                self._warn("quantification cancelled before any frame finished")
        else:
            self._report_failure("the quantification", job)
        return True

    def _report_failure(self, what: str, job: Job) -> None:
        e = job.error
        if isinstance(e, (ValueError, OSError)):
            self._error(f"{what} failed: {e}")
        else:
            self._error(f"{what} failed with an internal error ({type(e).__name__}: {e}); "
                        "details were printed to the terminal")
            if job.traceback:
                print(job.traceback, file=sys.stderr)

    def _take_result(self, result, surfaces, kwargs, keep_maps: bool, partial: bool) -> None:
        self.result, self.result_partial, self.result_stale = result, partial, False
        self.result_surfaces, self.result_settings = surfaces, kwargs
        self.result_has_maps = keep_maps
        self._overlay_vmax.clear()
        species = self.result_species()
        if species and self.display.overlay_species not in species:
            self.display.overlay_species = species[0]
        self.rev["result"] += 1

    # ================================================================= export
    def _need_result(self) -> bool:
        if self.result is None:
            return self._error("nothing to export yet: run the quantification first")
        return True

    def _export(self, what: str, fn) -> bool:
        try:
            written = fn()
        except (ExportError, ValueError, OSError) as e:
            return self._error(f"could not export the {what}: {e}")
        paths = written if isinstance(written, list) else [written]
        self._info(f"{what} written to {', '.join(str(p) for p in paths)}")
        self.store.set_last_dir(Path(paths[0]).parent)
        return True

    def export_csv(self, path) -> bool:
        """The rate time series as CSV (``Result.to_csv``)."""
        if not self._need_result():
            return False

        def go():
            p = check_writable(path)
            self.result.to_csv(str(p))
            return p
        return self._export("CSV", go)

    def export_json(self, path) -> bool:
        """The whole result as JSON (``Result.to_json``)."""
        if not self._need_result():
            return False

        def go():
            p = check_writable(path)
            self.result.to_json(str(p))
            return p
        return self._export("JSON", go)

    def export_plots(self, path) -> bool:
        """The rate plot as PNG (and the maps plot beside it when the run kept maps)."""
        if not self._need_result():
            return False
        return self._export("plots", lambda: write_plots(self.result, path,
                                                         maps=self.result_has_maps))

    def frame_picture(self, zoom: int = 3) -> np.ndarray:
        """What the image shows (frame, overlay, surfaces, region, source) as
        uint8 RGB, ``zoom`` times the recording's size."""
        rgba = self.render().copy()
        over = self.render_overlay()
        if over is not None:
            rgba = display.blend(rgba, over)
        src = None
        if self.settings.use_source:
            try:
                src = (float(self.settings.source_x), float(self.settings.source_y))
            except ValueError:
                src = None
        return render_frame_rgb(rgba, self.surfaces, self.region, zoom=zoom, source=src)

    def export_frame(self, path) -> bool:
        """The current frame as shown, as PNG."""
        if self.recording is None:
            return self._error("open a recording first: there is no frame to save")
        return self._export("frame", lambda: write_frame_png(path, self.frame_picture()))

    def report(self, files=()) -> str:
        return report_text(self.result, self.summary, self.result_surfaces,
                           self.result_settings, files)

    def export_report(self, path) -> bool:
        """The report of the result: a PDF (``qogi.report``, the same as
        ``qogi quantify --report``) when ``path`` ends in .pdf, else short Markdown."""
        if not self._need_result():
            return False
        if Path(os.fspath(path)).suffix.lower() == ".pdf":
            return self._export("report", lambda: write_pdf_report(self.result, path,
                                                                   self.recording))
        return self._export("report", lambda: write_report(path, self.report()))

    def export_all(self, folder, stem: str = "qogi") -> bool:
        """Everything into ``folder``: <stem>.csv (and .summary.csv), .json,
        _rates.png (and _rates_maps.png), _frame.png, _report.md and _report.pdf."""
        if not self._need_result():
            return False
        f = Path(os.fspath(folder)).expanduser()
        if not f.is_dir():
            return self._error(f"could not export: the folder {f} does not exist")
        ok = (self.export_csv(f / f"{stem}.csv") and self.export_json(f / f"{stem}.json")
              and self.export_plots(f / f"{stem}_rates.png")
              and self.export_frame(f / f"{stem}_frame.png"))
        if not ok:
            return False
        if not self.export_report(f / f"{stem}_report.pdf"):
            return False
        files = sorted(p for p in f.glob(f"{stem}*")
                       if p.suffix in (".csv", ".json", ".png", ".pdf"))
        return self._export("report", lambda: write_report(f / f"{stem}_report.md",
                                                           self.report(files)))

    # ================================================================= lifetime
    def close(self) -> None:
        """Stop any job, wait until it has stopped, and close the recording
        (window closing). The wait is not cut short: a job thread left inside
        the engine when the interpreter exits aborts the process; a cancelled
        job stops at its next progress report (a fraction of a second)."""
        if self.job is not None:
            self.job.cancel()
            interrupted = None
            while True:
                try:
                    if self.job.wait(0.1):
                        break
                except KeyboardInterrupt as e:  # finish waiting first
                    interrupted = e
            if interrupted is not None:
                raise interrupted
        if self.recording is not None:
            try:
                self.recording.close()
            except Exception:  # nothing useful to do about it while closing
                pass
