"""Replacing a library function for a test wherever qogi holds it.

qogi's modules import the names they use at module level
(``from ..pipeline import quantify``), so patching the defining module's
attribute alone leaves the callers' own bindings untouched and a test that
means to intercept a call would silently not. :func:`replace_everywhere`
patches every binding of the function in every loaded qogi module.
"""

from __future__ import annotations

import sys


def replace_everywhere(monkeypatch, real, fake) -> int:
    """Sets ``fake`` in place of every module-level binding of ``real`` in the
    loaded ``qogi`` modules (undone by ``monkeypatch``); returns how many."""
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
