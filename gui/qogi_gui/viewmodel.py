"""The viewer's state and actions, without any widget.

:class:`ViewModel` holds everything the window shows (the open recording, the
playback position and display settings, the drawn control surfaces and
background region, the analysis form, the running job and the result) and
every action a user can take (open, play, draw, configure, run, cancel,
export). The Dear PyGui layer (:mod:`qogi_gui.app`) only forwards input here
and draws what it finds, so all behaviour is tested without a screen.

The work is done by one panel object per part of the window
(:mod:`qogi_gui.panels`: ``vm.file``, ``vm.player``, ``vm.video``,
``vm.overlay``, ``vm.editor``, ``vm.form``, ``vm.work``, ``vm.run``,
``vm.exporter``, ``vm.log``); the view-model composes them, holds what
they share, and offers their actions under one name each (:data:`_FORWARD`).

Errors never escape an action: each one is turned into a readable
:class:`Message` (``vm.messages``; the newest is ``vm.last_message``) and the
action returns False.

The viewer uses only the public ``qogi`` API of docs/pipeline_api.md
(``open_recording``, ``Surface``, ``Region``, ``QuantifyConfig``,
``quantify``, ``Cancelled``, ``RecordingError``); the ``api`` argument lets
tests substitute an object with the same names.
"""

from __future__ import annotations

import time
from typing import Callable, Optional

from .panels.analysis import AnalysisForm
from .panels.drawing import MODES, SurfaceEditor
from .panels.exports import Exporter
from .panels.messages import MAX_MESSAGES, Message, MessageLog
from .panels.overlay import Overlay
from .panels.playback import SPEEDS, Playback
from .panels.recording import RecordingPanel
from .panels.run import RunPanel
from .panels.video import RANGE_MODES, DisplayState, Video
from .panels.work import Work
from .store import UserStore

__all__ = ["ViewModel", "Message", "MODES", "SPEEDS", "RANGE_MODES", "DisplayState", "MAX_MESSAGES"]

#: The view-model's names for its panels' state and actions: panel attribute ->
#: {view-model name: the panel's name}. Each is a read/write property of
#: :class:`ViewModel` (methods come back bound to their panel).
_FORWARD = {
    "log": {"messages": "messages", "last_message": "last"},
    "file": {
        n: n
        for n in (
            "open",
            "open_demo",
            "submit_scene",
            "cancel_scene",
            "scene_request",
            "summary",
            "metadata_rows",
            "set_recording",
        )
    }
    | {"recording_path": "path"},
    "player": {
        n: n
        for n in (
            "frame",
            "playing",
            "speed",
            "n_frames",
            "frame_time_s",
            "seek",
            "step",
            "play",
            "set_speed",
            "tick",
        )
    },
    "video": {
        n: n
        for n in (
            "display",
            "set_display",
            "unit",
            "current_frame",
            "channel_image",
            "auto_range",
            "display_range",
            "render",
            "last_range",
            "readout",
            "px_per_frame_to_m_s",
        )
    },
    "overlay": {
        "frame_maps": "frame_maps",
        "map_frames": "map_frames",
        "seek_map_frame": "seek_map_frame",
        "overlay_vmax": "vmax",
        "render_overlay": "render",
        "vectors": "vectors",
    },
    "editor": {
        n: n
        for n in (
            "mode",
            "surfaces",
            "drawing",
            "selected",
            "region",
            "region_corner",
            "set_mode",
            "click",
            "finish_drawing",
            "cancel_drawing",
            "undo_point",
            "add_surface",
            "auto_surfaces",
            "move_vertex",
            "delete_surface",
            "reverse_surface",
            "rename_surface",
            "set_region",
        )
    },
    "form": {n: n for n in ("settings", "field_errors", "update_settings", "validate_settings")},
    "work": {
        "job": "job",
        "job_kind": "kind",
        "busy": "busy",
        "progress": "progress",
        "poll": "poll",
        "cancel_run": "cancel",
    },
    "run": {
        n: n
        for n in (
            "result",
            "result_partial",
            "result_surfaces",
            "result_settings",
            "result_has_maps",
            "result_stale",
            "result_species",
            "start_run",
        )
    },
    "exporter": {
        n: n
        for n in (
            "export_csv",
            "export_json",
            "export_plots",
            "export_frame",
            "export_report",
            "export_all",
            "frame_picture",
            "report",
        )
    },
}


def _forwarded(panel: str, name: str) -> property:
    def get(self):
        return getattr(getattr(self, panel), name)

    def set_(self, value):
        setattr(getattr(self, panel), name, value)

    return property(get, set_, doc=f"``self.{panel}.{name}``")


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

    def __init__(
        self,
        api=None,
        store: Optional[UserStore] = None,
        demo_provider: Optional[Callable] = None,
        clock: Callable[[], float] = time.monotonic,
    ):
        if api is None:
            import qogi as api
        self.api = api
        self.store = store if store is not None else UserStore()
        if demo_provider is None:
            from .demo import ensure_demo as demo_provider
        self.clock = clock
        self.log = MessageLog()
        if self.store.warning:
            self.log.warn(self.store.warning)
        #: The open ``qogi.Recording`` (set by ``file``), shared by every panel.
        self.recording = None
        #: Bumped when the corresponding state changes, so the window redraws only then.
        self.rev = {
            "recording": 0,
            "surfaces": 0,
            "result": 0,
            "settings": 0,
            "display": 0,
            "scene_request": 0,
        }

        self.file = RecordingPanel(self, demo_provider)
        self.player = Playback(self)
        self.video = Video(self)
        self.overlay = Overlay(self)
        self.editor = SurfaceEditor(self)
        self.form = AnalysisForm(self)
        self.work = Work(self)
        self.run = RunPanel(self)
        self.exporter = Exporter(self)

    def panels(self) -> list:
        """The panels, in the order they start afresh on a new recording."""
        return [
            self.file,
            self.player,
            self.editor,
            self.form,
            self.run,
            self.overlay,
            self.video,
            self.work,
            self.exporter,
        ]

    def close(self) -> None:
        """Stop any job, wait until it has stopped, and close the recording
        (window closing); see :meth:`qogi_gui.panels.work.Work.close`."""
        self.work.close()
        if self.recording is not None:
            try:
                self.recording.close()
            except Exception:  # noqa: BLE001 - nothing useful to do about it while closing
                pass


for _panel, _names in _FORWARD.items():
    for _name, _target in _names.items():
        setattr(ViewModel, _name, _forwarded(_panel, _target))
del _panel, _names, _name, _target
