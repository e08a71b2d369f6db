"""``qogi.inversion``: the per-pixel inversion.

The path the documentation has always given (``from qogi.inversion import ...``);
the code lives in :mod:`qogi.measure.inversion`, at its place among the layers.
"""

from .measure.inversion import *  # noqa: F403
from .measure.inversion import __all__  # noqa: F401
