"""What every panel of the window holds: the App it belongs to and its view-model."""

from __future__ import annotations

__all__ = ["Panel"]


class Panel:
    """A part of the window, built by ``build`` and redrawn from ``app.vm``.

    Parameters
    ----------
    app : qogi_gui.app.App
        The window the panel belongs to; its view-model is kept as ``self.vm``.
    """

    def __init__(self, app):
        self.app = app
        self.vm = app.vm
