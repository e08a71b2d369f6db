"""Per-user state of the viewer: recent files, the last folder used, and the
scene facts given for each camera file (camera, distance, ...), remembered so
that a file opens directly the next time.

Stored as JSON in the user's configuration folder (the demo recording goes
to qogi's cache folder instead, see :func:`cache_dir`):
``$QOGI_CONFIG_DIR`` if set, else ``$XDG_CONFIG_HOME/qogi``, else
``~/.config/qogi`` (``viewer.json``). A missing or unreadable file means an
empty history; it never stops the viewer.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import List, Optional

__all__ = ["config_dir", "cache_dir", "UserStore", "MAX_RECENT", "SCENE_FACT_KEYS"]

#: The scene facts remembered per camera file.
SCENE_FACT_KEYS = ("camera", "distance_m", "ambient_temperature_K", "pressure_Pa")

#: How many recent recordings are remembered.
MAX_RECENT = 10
_FILE = "viewer.json"


def config_dir() -> Path:
    """The folder for the viewer's per-user settings."""
    env = os.environ.get("QOGI_CONFIG_DIR")
    if env:
        return Path(env)
    xdg = os.environ.get("XDG_CONFIG_HOME")
    return (Path(xdg) if xdg else Path.home() / ".config") / "qogi"


def cache_dir() -> Path:
    """The folder for regenerable files (the demo recording): qogi's per-user
    cache, ``$QOGI_CACHE_DIR`` or ``~/.cache/qogi`` (:func:`qogi.cache.cache_dir`)."""
    from qogi.cache import cache_dir as qogi_cache_dir

    return Path(qogi_cache_dir())


class UserStore:
    """Recent files and last folder, persisted as JSON.

    Parameters
    ----------
    folder : path, optional
        Where ``viewer.json`` lives; default :func:`config_dir`.

    Attributes
    ----------
    recent : list of str
        Absolute paths, most recent first, at most :data:`MAX_RECENT`.
    last_dir : str
        Folder of the last file opened or exported ("" if none).
    scene_facts : dict of str -> dict
        Per camera file (absolute path): the facts given in the viewer's
        form (``camera``, ``distance_m``, ``ambient_temperature_K``,
        ``pressure_Pa``; keyword arguments of ``qogi.open_recording``).
    warning : str
        Why the stored file could not be read or written ("" if it could).
    """

    def __init__(self, folder: Optional[os.PathLike] = None):
        self.folder = Path(folder) if folder is not None else config_dir()
        self.recent: List[str] = []
        self.last_dir = ""
        self.scene_facts: dict = {}
        self.warning = ""
        self._load()

    @property
    def path(self) -> Path:
        return self.folder / _FILE

    def _load(self) -> None:
        try:
            data = json.loads(self.path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return
        except (OSError, ValueError) as e:
            self.warning = f"could not read the viewer settings {self.path} ({e}); starting empty"
            return
        if not isinstance(data, dict):
            self.warning = f"viewer settings {self.path} are not a JSON object; starting empty"
            return
        recent = data.get("recent", [])
        if isinstance(recent, list):
            self.recent = [str(p) for p in recent if isinstance(p, str)][:MAX_RECENT]
        last = data.get("last_dir", "")
        self.last_dir = last if isinstance(last, str) else ""
        facts = data.get("scene_facts", {})
        if isinstance(facts, dict):
            self.scene_facts = {
                str(k): {
                    fk: fv
                    for fk, fv in v.items()
                    if fk in SCENE_FACT_KEYS and isinstance(fv, (str, int, float))
                }
                for k, v in facts.items()
                if isinstance(v, dict)
            }

    def save(self) -> bool:
        """Write the file; on failure set :attr:`warning` and return False."""
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            from qogi.files import atomic_open

            with atomic_open(self.path, "w", encoding="utf-8") as fh:
                fh.write(
                    json.dumps(
                        {
                            "recent": self.recent,
                            "last_dir": self.last_dir,
                            "scene_facts": self.scene_facts,
                        },
                        indent=1,
                    )
                )
        except OSError as e:
            self.warning = f"could not save the viewer settings to {self.path} ({e})"
            return False
        self.warning = ""
        return True

    def add_recent(self, path: os.PathLike) -> None:
        """Put ``path`` first in the recent list (and remember its folder), then save."""
        p = os.path.abspath(os.fspath(path))
        self.recent = [p] + [r for r in self.recent if r != p]
        del self.recent[MAX_RECENT:]
        self.last_dir = os.path.dirname(p)
        self.save()

    def remove_recent(self, path: os.PathLike) -> None:
        """Forget ``path`` (e.g. a file that no longer opens), then save."""
        p = os.path.abspath(os.fspath(path))
        if p in self.recent:
            self.recent.remove(p)
            self.save()

    def set_last_dir(self, folder: os.PathLike) -> None:
        self.last_dir = os.path.abspath(os.fspath(folder))
        self.save()

    def scene_for(self, path: os.PathLike) -> Optional[dict]:
        """The scene facts remembered for ``path`` (None if none)."""
        return self.scene_facts.get(os.path.abspath(os.fspath(path)))

    def set_scene(self, path: os.PathLike, facts: dict) -> None:
        """Remember the scene facts given for ``path``, then save."""
        self.scene_facts[os.path.abspath(os.fspath(path))] = {
            k: v for k, v in facts.items() if k in SCENE_FACT_KEYS and v not in (None, "")
        }
        self.save()
