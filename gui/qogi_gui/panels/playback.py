"""Playback: the shown frame, play/pause and speed, on the recording's own clock."""

from __future__ import annotations

from typing import Optional

import numpy as np

__all__ = ["Playback", "SPEEDS"]

#: Playback speeds (x real time).
SPEEDS = (0.1, 0.25, 0.5, 1.0, 2.0, 4.0)


class Playback:
    """The controls below the image. Frames follow the recording's own times
    (``time_s``), so a slow display shows the frame due at each redraw
    instead of falling behind."""

    def __init__(self, vm):
        self.vm = vm
        self.frame = 0
        self.playing = False
        self.speed = 1.0
        self._play_t = 0.0  # playback time since the first frame [s]
        self._last_tick: Optional[float] = None

    def reset(self, recording) -> None:
        self.frame, self._play_t, self.playing = 0, 0.0, False

    @property
    def n_frames(self) -> int:
        rec = self.vm.recording
        return rec.n_frames if rec is not None else 0

    @property
    def frame_time_s(self) -> float:
        rec = self.vm.recording
        if rec is None:
            return 0.0
        return float(rec.time_s[self.frame] - rec.time_s[0])

    def seek(self, frame: int) -> None:
        """Show frame ``frame`` (clamped to the recording)."""
        if self.vm.recording is None:
            return
        self.frame = int(min(max(int(frame), 0), self.n_frames - 1))
        self._play_t = self.frame_time_s

    def step(self, n: int = 1) -> None:
        self.playing = False
        self.seek(self.frame + n)

    def play(self, on: Optional[bool] = None) -> None:
        """Start or stop playback (toggle when ``on`` is None)."""
        if self.vm.recording is None:
            return
        self.playing = (not self.playing) if on is None else bool(on)
        self._last_tick = self.vm.clock()
        if self.playing and self.frame >= self.n_frames - 1:
            self.seek(0)

    def set_speed(self, speed: float) -> bool:
        try:
            v = float(speed)
        except (TypeError, ValueError):
            return self.vm.log.error(f"playback speed must be a number; got {speed!r}")
        if not 0 < v <= 100:
            return self.vm.log.error(f"playback speed must be in (0, 100] x real time; got {v:g}")
        self.speed = v
        return True

    def tick(self) -> bool:
        """Advance playback to the clock; True if the shown frame changed.
        Frames follow the recording's own times (``time_s``), looping at the end."""
        rec = self.vm.recording
        now = self.vm.clock()
        last, self._last_tick = self._last_tick, now
        if not self.playing or rec is None or last is None:
            return False
        t = rec.time_s
        self._play_t += (now - last) * self.speed
        period = float(t[-1] - t[0]) + 1.0 / float(rec.camera.frame_rate_hz)
        if self._play_t >= period:
            self._play_t %= period
        i = int(np.searchsorted(t - t[0], self._play_t, side="right")) - 1
        i = min(max(i, 0), self.n_frames - 1)
        changed = i != self.frame
        self.frame = i
        return changed
