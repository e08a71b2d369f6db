"""qogi viewer: a desktop window on top of the public ``qogi`` Python API.

A technician opens a recording (or the demo scene), plays it, draws control
surfaces with the mouse, sets the analysis, runs the quantification in the
background and reads the emission rate; results export as CSV, JSON, PNG and
a short report.

Two layers:

- :mod:`qogi_gui.viewmodel` and its helpers (:mod:`~qogi_gui.display`,
  :mod:`~qogi_gui.surfaces`, :mod:`~qogi_gui.settings`, :mod:`~qogi_gui.jobs`,
  :mod:`~qogi_gui.export`, :mod:`~qogi_gui.store`, :mod:`~qogi_gui.demo`):
  plain Python state, actions and results, no Dear PyGui import; unit-tested
  without a screen.
- :mod:`qogi_gui.app`: the Dear PyGui widgets, which only forward user input
  to the view-model and draw what it holds.

Start it with ``qogi gui [REC.h5]``, ``make gui`` or ``python -m qogi_gui``.
"""

from __future__ import annotations

import sys

__all__ = ["main", "launch"]


def main(path=None, scene=None) -> int:
    """Open the viewer window (optionally on the recording or camera file
    ``path``, with the scene facts ``scene`` for a camera file); returns when
    the window is closed. Needs Dear PyGui and a display."""
    from .app import run

    return run(path, scene=scene)


def launch(path=None, scene=None) -> int:
    """``qogi gui``: the viewer as an app of the command line (entry point
    ``gui`` of the group ``qogi.apps``, so that the library never imports the
    viewer). Like :func:`main`, but a missing Dear PyGui or display is an
    error message and exit status 2, not a traceback."""
    try:
        from .app import NoDisplayError
    except ImportError as e:
        print(
            f"qogi gui: error: the viewer needs Dear PyGui and matplotlib ({e}); install them "
            "with: pip install 'qogi[gui]'",
            file=sys.stderr,
        )
        return 2
    try:
        return main(path, scene=scene)
    except NoDisplayError as e:
        print(f"qogi gui: error: {e}", file=sys.stderr)
        return 2
