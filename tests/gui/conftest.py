"""Fixtures for the viewer's tests: a per-test user store, small recordings
whose frames are blackbody radiances of known temperatures (exact truth), and
a view-model on the real API, watched (Instrumented)."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import qogi

W, H, T, RATE_HZ = 32, 24, 8, 10.0
# The air (and the gas, at ambient) is warmer than every pixel of the plate and
# its blob (at most 310.5 K), so the blob reads as hot gas in emission: a blob
# hotter than the gas could not be gas at all (qogi's proxy reads it as none).
AMBIENT_K = 320.0


def channels():
    return [
        qogi.SpectralResponse([2941.18, 3125.0], [1.0, 1.0], name="3.2-3.4 um"),
        qogi.SpectralResponse([2000.0, 2200.0], [1.0, 1.0], name="4.5-5.0 um"),
    ]


def temperature_field(n_frames=T, height=H, width=W):
    """Blackbody temperatures [K] (T, H, W): a warm blob drifting up the frame
    (as gas at AMBIENT_K, hotter than the 285 K plate, would look)."""
    t = np.arange(n_frames)[:, None, None]
    y = np.arange(height)[None, :, None]
    x = np.arange(width)[None, None, :]
    blob = np.exp(-((x - width / 2) ** 2 + (y - (height - 4 - t)) ** 2) / 20.0)
    return 285.0 + 0.5 * x / width + 25.0 * blob


def make_recording(n_channels=2, species=("CH4",), truth_kg_s=None, n_frames=T, nan=False):
    chs = channels()[:n_channels]
    temp = temperature_field(n_frames)
    frames = np.stack([ch.band_radiance(temp.ravel()).reshape(temp.shape) for ch in chs], axis=1)
    if nan:
        frames[3, 0, 5, 7] = np.nan
    cam = qogi.Camera("test camera", 1e-3, chs, frame_rate_hz=RATE_HZ, netd_K=0.02)
    scene = qogi.Scene(
        distance_m=3.0,
        ambient_temperature_K=AMBIENT_K,
        pressure_Pa=101325.0,
        species=tuple(species),
    )
    truth = qogi.Truth({"CH4": truth_kg_s}) if truth_kg_s else None
    return qogi.Recording.from_arrays(
        frames,
        quantity="radiance",
        camera=cam,
        scene=scene,
        truth=truth,
        nonfinite="invalid" if nan else "error",
    )


@pytest.fixture
def rec_path(tmp_path):
    p = tmp_path / "small.h5"
    make_recording(truth_kg_s=1e-3).save(p)
    return p


@pytest.fixture
def store(tmp_path):
    from qogi_gui.store import UserStore

    return UserStore(tmp_path / "config")


def wait_for(cond, timeout=5.0):
    """Waits until cond() holds (an assertion error after ``timeout`` s)."""
    end = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < end, "timed out"
        time.sleep(0.002)


class Clock:
    def __init__(self):
        self.t = 100.0

    def __call__(self):
        return self.t


class Instrumented:
    """The real ``qogi`` API, watched: every ``quantify`` call is recorded, and
    a test may hold the run before each progress report until it lets one
    through (``hold()``, ``step()``, ``release()``) or make it fail at the
    ``fail_at``-th report (``fail_with``), to reach the viewer's running,
    cancelling and failure states deterministically. The numbers are the real
    pipeline's."""

    def __init__(self):
        self.calls = []
        self.gate = None  # a Semaphore: one permit per progress report
        self.reports = []  # (fraction, message) of the reports let through
        self.fail_at = None
        self.fail_with = RuntimeError("engine exploded")

    def hold(self):
        self.gate = threading.Semaphore(0)

    def step(self, timeout=10.0):
        """Let one progress report through and wait until the viewer has seen it."""
        n = len(self.reports)
        self.gate.release()
        wait_for(lambda: len(self.reports) > n, timeout)
        return self.reports[-1]

    def release(self):
        gate, self.gate = self.gate, None
        if gate is not None:
            gate.release(1000)

    def __getattr__(self, name):
        return getattr(qogi, name)

    def quantify(self, recording, surfaces, config=None, progress=None, keep_maps=False):
        self.calls.append((surfaces, config, keep_maps))
        seen = [0]

        def watched(fraction, message):
            seen[0] += 1
            gate = self.gate
            if gate is not None:
                gate.acquire(timeout=10)
            if self.fail_at is not None and seen[0] >= self.fail_at:
                raise self.fail_with
            go = progress(fraction, message) if progress is not None else None
            self.reports.append((fraction, message))
            return go

        return qogi.quantify(recording, surfaces, config, progress=watched, keep_maps=keep_maps)


@pytest.fixture
def api():
    a = Instrumented()
    yield a
    a.release()


@pytest.fixture
def vm(api, store, rec_path):
    from qogi_gui.viewmodel import ViewModel

    v = ViewModel(api=api, store=store, demo_provider=lambda progress: str(rec_path), clock=Clock())
    yield v
    v.close()
