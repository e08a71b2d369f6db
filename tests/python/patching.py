"""Replacing a library function for a test wherever qogi holds it.

qogi's modules import the names they use at module level
(``from ..pipeline import quantify``), so patching the defining module's
attribute alone leaves the callers' own bindings untouched and a test that
means to intercept a call would silently not. :func:`replace_everywhere`
patches every binding of the function in every qogi module, after loading
them all: a module first imported while the fake is in place would bind the
fake for good (monkeypatch restores only what it patched).
"""

from __future__ import annotations

import importlib
import pkgutil
import sys

import qogi


def replace_everywhere(monkeypatch, real, fake) -> int:
    """Sets ``fake`` in place of every module-level binding of ``real`` in the
    ``qogi`` modules (undone by ``monkeypatch``); returns how many."""
    for info in pkgutil.walk_packages(qogi.__path__, "qogi."):
        if not info.name.endswith("__main__"):
            try:
                importlib.import_module(info.name)
            except ImportError:  # an optional app's dependency (Dask) is missing
                pass
    for name in qogi.__all__:  # the package's lazy names, cached before the fake exists
        getattr(qogi, name)
    n = 0
    for name, module in list(sys.modules.items()):
        if module is None or not (name == "qogi" or name.startswith("qogi.")):
            continue
        for attr, value in list(vars(module).items()):
            if value is real:
                monkeypatch.setattr(module, attr, fake)
                n += 1
    assert n, f"{real!r} is bound in no loaded qogi module"
    return n
