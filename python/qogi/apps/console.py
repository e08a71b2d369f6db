"""The ``qogi`` console script's entry (``python -m qogi`` too).

Only this module, ``qogi``'s lazy package and :mod:`qogi.errors` load before
the guard: the command line itself (:mod:`.cli`, argparse and the rest) is
imported inside it, so a Ctrl-C while it loads is exit 130 and one line, not a
KeyboardInterrupt traceback. What remains unguarded is Python's own start-up
(``site``) and the ~1 ms import of these three small modules.
"""

from __future__ import annotations

import sys

from ..errors import EXIT_INTERRUPTED


def main(argv: list[str] | None = None) -> int:
    """Loads the command line and runs one command (:func:`qogi.apps.cli.main`)."""
    try:
        # start-up: deferred so that a Ctrl-C while the command line loads is exit 130
        from .cli import main as run
    except KeyboardInterrupt:
        print("qogi: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return run(argv)
