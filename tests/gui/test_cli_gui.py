"""`qogi gui`: wired into the command line, with clear errors instead of a crash."""

from __future__ import annotations

import os
import subprocess
import sys


def qogi(*args, env=None):
    return subprocess.run(
        [sys.executable, "-m", "qogi", *args], capture_output=True, check=False, text=True, env=env
    )


def test_help_lists_the_viewer():
    out = qogi("--help").stdout
    assert "gui" in out and "desktop viewer" in out
    out = " ".join(qogi("gui", "--help").stdout.split())
    assert "recording (.h5) or camera file (.seq, .csq, .jpg, .fff, .hcc) to open" in out
    assert "--camera" in out and "--distance" in out


def test_missing_file_is_an_error_not_a_window(tmp_path):
    r = qogi("gui", str(tmp_path / "none.h5"))
    assert r.returncode == 2 and "no such file" in r.stderr


def test_no_display_is_explained():
    env = {k: v for k, v in os.environ.items() if k != "DISPLAY"}
    r = qogi("gui", env=env)
    assert r.returncode == 2
    assert "DISPLAY is not set" in r.stderr and "xvfb-run" in r.stderr


def test_unreachable_display_is_explained():
    r = qogi("gui", env=dict(os.environ, DISPLAY=":987"))
    assert r.returncode == 2 and "cannot open the X display ':987'" in r.stderr
