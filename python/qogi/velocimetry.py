"""``qogi.velocimetry``: optical flow and the gas's transport velocity.

The path the documentation has always given (``from qogi import velocimetry``);
the code lives in :mod:`qogi.measure.velocimetry`, at its place among the layers.
"""

from .measure.velocimetry import *  # noqa: F403
from .measure.velocimetry import __all__  # noqa: F401
