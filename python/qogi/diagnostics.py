"""Machine-readable warnings attached to a result.

A :class:`Diagnostic` says that part of a result cannot be fully trusted, why,
and where (surface, species). Every stage of the pipeline that notices
something appends one; the result's JSON carries them as ``warnings``, the
command line prints them, and the viewer shows them. Codes are stable strings
(documented in docs/pipeline_api.md), messages are for people.
"""

from __future__ import annotations

import dataclasses
from typing import Iterable, List, Optional

__all__ = ["Diagnostic", "Diagnostics"]


@dataclasses.dataclass(frozen=True)
class Diagnostic:
    """One warning: ``code`` (stable, e.g. ``"frames-dropped"``), ``message``
    (for people: what, how big, what to do), and optionally the ``surface``
    name and ``species`` it concerns, and ``data`` (numbers behind it)."""

    code: str
    message: str
    surface: Optional[str] = None
    species: Optional[str] = None
    data: Optional[dict] = None

    def to_dict(self) -> dict:
        d: dict = {"code": self.code, "message": self.message}
        if self.surface is not None:
            d["surface"] = self.surface
        if self.species is not None:
            d["species"] = self.species
        if self.data:
            d["data"] = dict(self.data)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> Diagnostic:
        return cls(
            code=str(d["code"]),
            message=str(d["message"]),
            surface=d.get("surface"),
            species=d.get("species"),
            data=d.get("data"),
        )

    def __str__(self) -> str:
        where = "/".join(x for x in (self.surface, self.species) if x)
        return f"[{self.code}{' ' + where if where else ''}] {self.message}"


class Diagnostics(List[Diagnostic]):
    """A list of :class:`Diagnostic` with a helper to add one and look up codes."""

    def add(
        self,
        code: str,
        message: str,
        *,
        surface: Optional[str] = None,
        species: Optional[str] = None,
        **data,
    ) -> Diagnostic:
        d = Diagnostic(code, message, surface, species, data or None)
        self.append(d)
        return d

    def codes(self) -> List[str]:
        return [d.code for d in self]

    def has(self, code: str) -> bool:
        return any(d.code == code for d in self)

    def extend_unique(self, items: Iterable[Diagnostic]) -> None:
        for d in items:
            if d not in self:
                self.append(d)
