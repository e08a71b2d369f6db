"""What an installed qogi needs: its engine and opencv-python-headless in one
process (both orders of import), each computing flow correctly."""

from __future__ import annotations

import pathlib
import subprocess
import sys

import pytest

SCRIPT = pathlib.Path(__file__).resolve().parents[2] / "scripts" / "opencv_coexistence.py"


@pytest.mark.parametrize("order", ["qogi-first", "cv2-first"])
def test_qogi_and_cv2_share_a_process(order):
    r = subprocess.run(
        [sys.executable, str(SCRIPT), order],
        capture_output=True,
        check=False,
        text=True,
        timeout=120,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    assert "qogi horn_schunck" in r.stdout
