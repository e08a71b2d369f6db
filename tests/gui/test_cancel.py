"""The viewer's cancel and close at any moment of a run, without a screen:
the job ends (cancelled or done), no engine thread is left behind, and a
process that closes the viewer mid-run exits cleanly (it used to be able to
abort: "terminate called without an active exception")."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import threading

import pytest

import qogi
from qogi_gui.jobs import CANCELLED, DONE
from qogi_gui.viewmodel import ViewModel


class CancelAt:
    """The real qogi API; the viewer's run is cancelled from the job's own
    thread at the ``at``-th progress report (as a click on Cancel would land)."""

    def __init__(self, at):
        self.at, self.vm = at, None

    def __getattr__(self, name):
        return getattr(qogi, name)

    def quantify(self, recording, surfaces, config=None, progress=None, keep_maps=False):
        seen = [0]

        def watched(fraction, message):
            seen[0] += 1
            if seen[0] == self.at:
                self.vm.job.cancel()
            return progress(fraction, message)

        return qogi.quantify(recording, surfaces, config, progress=watched, keep_maps=keep_maps)


def engine_threads():
    return [
        t.name
        for t in threading.enumerate()
        if t.name.startswith("qogi-") and not t.name.startswith("qogi-gui")
    ]


@pytest.mark.parametrize("at", [1, 2, 3, 6, 10])
def test_cancel_at_each_early_report_ends_the_job_and_its_engine_threads(store, rec_path, at):
    api = CancelAt(at)
    vm = ViewModel(api=api, store=store, demo_provider=lambda progress: str(rec_path))
    api.vm = vm
    try:
        assert vm.open(rec_path), vm.last_message
        vm.add_surface([(4, 12), (28, 12)])
        assert vm.start_run()
        assert vm.job.wait(60), "the cancelled job never ended"
        vm.poll()
        assert vm.progress()["state"] in (CANCELLED, DONE)
        if vm.progress()["state"] == CANCELLED and vm.result is not None:
            assert not vm.result.complete  # a partial result says so
        assert engine_threads() == []
    finally:
        vm.close()


SCRIPT = textwrap.dedent("""
    import sys, time
    from qogi_gui.store import UserStore
    from qogi_gui.viewmodel import ViewModel
    rec, config, delay, cancel = sys.argv[1], sys.argv[2], float(sys.argv[3]), sys.argv[4] == "1"
    vm = ViewModel(store=UserStore(config))
    assert vm.open(rec), vm.last_message
    vm.add_surface([(4, 12), (28, 12)])
    assert vm.start_run()
    time.sleep(delay)
    if cancel and vm.busy:
        vm.cancel_run()
    vm.close()  # the window closing: waits for the job, however far it got
    print("closed", vm.progress()["state"])
""")


@pytest.mark.parametrize("delay_s, cancel", [(0.0, True), (0.2, True), (0.5, False)])
def test_closing_the_viewer_mid_run_exits_cleanly(rec_path, tmp_path, delay_s, cancel):
    r = subprocess.run(
        [
            sys.executable,
            "-c",
            SCRIPT,
            str(rec_path),
            str(tmp_path / "config"),
            str(delay_s),
            "1" if cancel else "0",
        ],
        capture_output=True,
        check=False,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stderr
    assert "closed" in r.stdout
    assert "terminate called" not in r.stderr and "FATAL" not in r.stderr
