"""Smoke test of the real viewer window under a virtual X server (Xvfb).

Starts Xvfb, runs tests/gui/window_driver.py in it (a separate process: the
window owns its OpenGL context and render loop), which loads the demo scene,
draws surfaces through the window's click handler, runs the real
quantification to the end and saves screenshots; then checks what came out.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.gui

HERE = Path(__file__).resolve().parent


@pytest.fixture(scope="module")
def xvfb():
    """A private X display (":N") served by Xvfb, stopped afterwards."""
    exe = shutil.which("Xvfb")
    if exe is None:
        pytest.fail("Xvfb is not installed: run scripts/setup_system.sh (Debian package xvfb)")
    r, w = os.pipe()
    proc = subprocess.Popen(
        [exe, "-displayfd", str(w), "-screen", "0", "1600x1000x24", "-nolisten", "tcp", "-noreset"],
        pass_fds=(w,),
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    os.close(w)
    with os.fdopen(r) as f:
        number = f.readline().strip()
    if not number:
        proc.kill()
        err = proc.stderr.read().decode(errors="replace")
        proc.stderr.close()
        proc.wait()
        pytest.fail(f"Xvfb did not start: {err}")
    yield f":{number}"
    proc.terminate()
    try:
        proc.wait(10)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    proc.stderr.close()


def _png(path: Path) -> np.ndarray:
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    assert img is not None, f"{path} is not a readable image"
    return img


def test_window_end_to_end(xvfb, tmp_path):
    env = dict(os.environ, DISPLAY=xvfb, QOGI_CONFIG_DIR=str(tmp_path / "config"))
    proc = subprocess.run(
        [sys.executable, str(HERE / "window_driver.py"), str(tmp_path)],
        env=env,
        capture_output=True,
        check=False,
        text=True,
        timeout=1200,
    )
    assert proc.returncode == 0, f"driver failed:\n{proc.stdout}\n{proc.stderr}"
    state = json.loads((tmp_path / "state.json").read_text())
    assert not [m for m in state["messages"] if m[0] == "error"], state["messages"]

    # Screenshots of every main state: the whole window, with content.
    assert state["shots"] == [
        "viewer_demo.png",
        "viewer_surfaces.png",
        "viewer_analysis.png",
        "viewer_running.png",
        "viewer_results.png",
    ]
    for name in state["shots"]:
        img = _png(tmp_path / name)
        assert img.shape[:2] == (900, 1440), (name, img.shape)
        assert img[..., :3].std() > 10, f"{name} looks blank"
    # The results screenshot differs from the one before the run (rates, overlay).
    before = _png(tmp_path / "viewer_analysis.png")[..., :3].astype(int)
    after = _png(tmp_path / "viewer_results.png")[..., :3].astype(int)
    assert np.mean(np.abs(after - before)) > 5

    # The window kept drawing while the quantification ran.
    assert state["running_frames"] >= 10 and state["distinct_progress"] >= 3

    # Real mouse clicks (XTEST) landed where they were aimed: the line's ends and
    # the polyline's points, ended by a right click; dragging moved a point up.
    drawn = {s["name"]: s["points"] for s in state["drawn"]}
    clicked = drawn["S1"] + drawn["S3"]
    clicked[3] = state["drag"]["before"]
    np.testing.assert_allclose(clicked, state["aimed"], atol=1e-6)
    assert len(drawn["S3"]) == 3
    (bx, by), (ax, ay) = state["drag"]["before"], state["drag"]["after"]
    assert abs(ax - bx) < 1.0 and 2.0 < by - ay < 8.0

    # The surfaces reached the pipeline as drawn, and the sign convention held
    # end to end: the same line walked the other way gives the opposite rate.
    rows = {r["surface"]: r for r in state["rows"]}
    assert set(rows) == {"S1", "S2", "S3"}
    s1, s2 = rows["S1"], rows["S2"]
    assert s1["n_frames"] == state["n_frames"]
    assert s1["mean_kg_h"] > 0, "upward flow through a left-to-right line must count positive"
    assert s2["mean_kg_h"] < 0
    truth = s1["truth_kg_h"]
    assert truth is not None and truth > 0
    exported = json.loads((tmp_path / "export" / "qogi.json").read_text())
    ex = {s["name"] if "name" in s else s["surface"]["name"]: s for s in exported["surfaces"]}
    assert ex["S1"]["species"]["CH4"]["mean_kg_h"] == pytest.approx(s1["mean_kg_h"])
    assert state["overlay_shown"] and state["vectors"] > 0
    for name in ("qogi.csv", "qogi_rates.png", "qogi_frame.png", "qogi_report.md"):
        assert (tmp_path / "export" / name).stat().st_size > 0

    # The analysis form's line-shape and exit-temperature fields (issue 18): a
    # bad value is a message beside its field; the run used the default rule.
    assert state["field_message"] == "must be within [150, 900] K; got 900.5"
    assert state["line_shape"] == "fixed:25+self"
    # The Results tab shows each term of the budget, the line shape among them,
    # and every warning of the exported result.
    texts = state["results_texts"]
    i = texts.index("1 sigma [kg/h]")
    assert "  line shape" in texts[i:], texts
    for w in exported["warnings"]:
        where = "/".join(x for x in (w.get("surface"), w.get("species")) if x)
        assert f"[{w['code']}{' ' + where if where else ''}] {w['message']}" in texts, texts
