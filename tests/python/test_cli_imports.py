"""The library does not depend on its viewer: importing the command line and
running ``qogi --help`` loads neither qogi_gui nor Dear PyGui (the ``gui``
subcommand imports them when it runs)."""

from __future__ import annotations

import subprocess
import sys

CHECK = """
import sys
import qogi.apps.cli
try:
    qogi.apps.cli.main(["--help"])
except SystemExit:
    pass
loaded = sorted(m for m in sys.modules if m.split(".")[0] in ("qogi_gui", "dearpygui"))
print("LOADED", loaded)
"""


def test_qogi_help_does_not_import_the_viewer():
    out = subprocess.run(
        [sys.executable, "-c", CHECK], capture_output=True, text=True, timeout=120, check=True
    ).stdout
    assert "LOADED []" in out, out
    assert "usage: qogi" in out
