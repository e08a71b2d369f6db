"""``qogi.batch``: batch runs on Dask.

The path the documentation has always given (``from qogi.batch import ...``);
the code lives in :mod:`qogi.apps.batch`, at its place among the layers.
"""

from .apps.batch import *  # noqa: F403
from .apps.batch import __all__  # noqa: F401
