"""The analysis form's panel: the fields as typed, and their messages.

The fields and their checks are :class:`qogi_gui.settings.AnalysisSettings`;
this panel keeps the form of the open recording and tells the others what
changed."""

from __future__ import annotations

from typing import Dict, Optional, Tuple

from ..settings import AnalysisSettings

__all__ = ["AnalysisForm"]


class AnalysisForm:
    """The Analysis tab."""

    def __init__(self, vm):
        self.vm = vm
        self.settings = AnalysisSettings()
        self.field_errors: Dict[str, str] = {}

    def reset(self, recording) -> None:
        self.settings = AnalysisSettings.for_recording(recording)
        self.field_errors = {}

    def update_settings(self, **fields) -> Dict[str, str]:
        """Set form fields (names of :class:`AnalysisSettings`), as typed by the
        user, and return the per-field messages of the whole form. (The form's
        widgets already show these values, so ``rev["settings"]`` is not bumped;
        it is for changes made elsewhere, e.g. a source picked on the image.)"""
        for k, v in fields.items():
            if not hasattr(self.settings, k):
                self.vm.log.error(f"unknown setting {k!r}")
                continue
            setattr(self.settings, k, v)
            if k in ("use_source", "source_x", "source_y"):
                self.vm.rev["surfaces"] += 1  # the source marker on the image
        self.vm.run.inputs_changed()
        return self.validate_settings()

    def validate_settings(self) -> Dict[str, str]:
        self.field_errors = self.settings.validate(self.vm.recording, self.vm.editor.region)
        return self.field_errors

    def set_source(self, x: float, y: float) -> None:
        """The source picked on the image or detected (x, y) [px]."""
        s = self.settings
        s.use_source = True
        s.source_x, s.source_y = f"{x:.1f}", f"{y:.1f}"
        self.vm.rev["settings"] += 1

    def source_point(self) -> Optional[Tuple[float, float]]:
        """The source (x, y) [px] when one is set and readable, else None."""
        s = self.settings
        if not s.use_source:
            return None
        try:
            return float(s.source_x), float(s.source_y)
        except ValueError:
            return None
