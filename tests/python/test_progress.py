"""qogi's one progress protocol and cancellation type, and its one helper for
background work (qogi.progress, qogi.errors.Cancelled, qogi.workers)."""

from __future__ import annotations

import pickle
import threading

import pytest

import qogi
import qogi.errors
import qogi.pipeline
from qogi.progress import fraction_callback, report
from qogi.workers import Workers, current, owned_workers


def test_one_cancellation_class_everywhere():
    assert qogi.Cancelled is qogi.errors.Cancelled is qogi.pipeline.Cancelled
    assert issubclass(qogi.Cancelled, Exception)
    assert not issubclass(qogi.Cancelled, KeyboardInterrupt)
    e = pickle.loads(pickle.dumps(qogi.Cancelled("stopped", partial={"frames": 3})))
    assert str(e) == "stopped" and e.partial == {"frames": 3}


def test_report_clamps_and_only_false_cancels():
    seen = []
    report(lambda f, m: seen.append((f, m)), 1.5, "x")
    report(lambda f, m: seen.append((f, m)) or True, -0.5, "y")
    report(None, 0.5, "nobody listens")
    assert seen == [(1.0, "x"), (0.0, "y")]
    with pytest.raises(qogi.Cancelled):
        report(lambda f, m: False, 0.5, "stop")


def test_fraction_callback_maps_a_part_of_the_whole_and_passes_a_stop_on():
    seen = []
    cb = fraction_callback(lambda f, m: seen.append((f, m)), "columns", 0.2, 0.6)
    assert cb(0.0) is True and cb(1.0) is True
    assert seen == [(0.2, "columns"), (pytest.approx(0.6), "columns")]
    assert fraction_callback(lambda f, m: False)(0.5) is False
    assert fraction_callback(None) is None


def test_a_task_returns_its_value_or_reraises_its_error_on_the_caller():
    with owned_workers() as w:
        assert current() is w
        ok = w.submit(lambda: 41 + 1, "qogi-test-ok")
        bad = w.submit(lambda: 1 / 0, "qogi-test-bad")
        assert ok.result() == 42
        with pytest.raises(ZeroDivisionError):
            bad.result()
    assert current() is not w


def test_close_cancels_and_waits_for_every_owned_thread():
    w = Workers()
    started, left = threading.Event(), threading.Event()

    def work():
        started.set()
        while w.still_wanted():
            threading.Event().wait(0.01)
        left.set()

    w.start(work, "qogi-test-loop")
    assert started.wait(5)
    w.close()
    assert left.is_set()  # close returned only after the thread left its loop
