"""Survey-scale batch quantification on Dask (``qogi batch``).

A **manifest** lists the recordings, one row each, with the settings of
:func:`qogi.quantify` for that row; defaults for every row sit in one place.
:func:`run` validates the whole manifest, then quantifies each row as one Dask
task on a :class:`distributed.LocalCluster` sized to this machine, or on an
existing cluster given by its scheduler address. Each task writes its own
result (``OUTDIR/<name>/result.json``, atomic) and optional plots; one summary
table (``OUTDIR/summary.csv`` and ``.parquet``) is assembled at the end (and
every few seconds while running). A failed recording is recorded in its row
and does not stop the others; ``resume=True`` skips rows whose result exists
with the same config hash, so a killed batch loses nothing.

The stages, visible in :func:`run`: load and validate the manifest -> the jobs
(config hash, rows already done) -> the cluster -> ``client.map`` -> collect as
completed -> the summary. The manifest format, the cluster set-up and what a
failure looks like are in docs/batch.md.
"""

from __future__ import annotations

import csv
import dataclasses
import glob
import hashlib
import json
import math
import os
import pathlib
import re
import sys
import time
import traceback
from typing import Any, Dict, List, Optional, Sequence, Tuple, Union

from .._progress import ProgressBar
from .._version import __version__
from ..diagnostics import Diagnostics
from ..errors import Cancelled, UsageError
from ..files import _TMP_PREFIX, atomic_open, atomic_path, check_outputs
from ..io.hdf5 import open_recording
from ..physics.optics import channel_problem
from ..physics.presets import camera_preset, camera_preset_names
from ..pipeline import QuantifyConfig, quantify
from ..pipeline.settings import SettingError, from_value
from ..pipeline.surfaces import Surface, auto_surfaces, plume_image

__all__ = [
    "Row",
    "load_manifest",
    "manifest_keys",
    "run",
    "run_row",
    "summary_frame",
    "SUMMARY_CSV",
    "SUMMARY_PARQUET",
    "RESULT_JSON",
    "FAILURE_JSON",
]

SUMMARY_CSV = "summary.csv"
SUMMARY_PARQUET = "summary.parquet"
RESULT_JSON = "result.json"
FAILURE_JSON = "failure.json"

#: Keys a manifest row (or ``[defaults]``) may set besides the QuantifyConfig
#: fields (docs/batch.md).
BATCH_KEYS = (
    "path",
    "name",
    "surfaces",
    "auto_distances_px",
    "camera",
    "ifov_rad",
    "plots",
    "timeout_s",
)
#: QuantifyConfig fields qogi batch sets itself.
_RESERVED = ("num_threads",)
#: A recording's analysis memory is a few times its frames; a 60 s GF320 clip
#: is ~0.3 GB of float32 frames. Default workers leave this much per worker.
_MEMORY_PER_WORKER = 2 << 30
_NAME_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9._-]*$")
_SUMMARY_INTERVAL_S = 10.0


def _config_fields() -> List[str]:

    return [name for name in QuantifyConfig.field_names() if name not in _RESERVED]


def manifest_keys() -> List[str]:
    """Every key a manifest row may set."""
    return list(BATCH_KEYS) + list(_config_fields())


# ---------------------------------------------------------------------------
# The manifest


@dataclasses.dataclass
class Row:
    """One recording of a batch, validated.

    ``surfaces`` is ``"auto"`` (placed by :func:`qogi.auto_surfaces` at
    ``auto_distances_px`` [px] from the source) or a list of polylines (each a
    list of (x, y) pixel points). ``config`` is the row's
    :class:`qogi.QuantifyConfig` (``num_threads`` is set per worker).
    ``camera`` (a :func:`qogi.camera_preset` name) and ``ifov_rad`` [rad]
    replace the recording's camera model; ``timeout_s`` [s] cancels the row
    when exceeded; ``where`` says where the row was written (for messages).
    """

    name: str
    path: str
    surfaces: Union[str, List[List[Tuple[float, float]]]]
    auto_distances_px: Optional[List[float]]
    config: Any
    camera: Optional[str] = None
    ifov_rad: Optional[float] = None
    plots: bool = False
    timeout_s: Optional[float] = None
    where: str = ""

    def settings(self) -> dict:
        """What the result depends on: the analysis settings and the
        recording's identity (resolved path, size, modification time). Output
        options (plots, timeout) and the thread count are not part of it."""
        cfg = self.config.to_dict()
        cfg.pop("num_threads", None)
        try:
            st = os.stat(self.path)
            ident = {"size": st.st_size, "mtime_ns": st.st_mtime_ns}
        except OSError:
            ident = {}
        return {
            "recording": {"path": os.path.abspath(self.path), **ident},
            "surfaces": self.surfaces,
            "auto_distances_px": self.auto_distances_px,
            "camera": self.camera,
            "ifov_rad": self.ifov_rad,
            "config": cfg,
        }

    def config_hash(self) -> str:
        """16 hex digits of the SHA-256 of :meth:`settings` (canonical JSON)."""
        text = json.dumps(self.settings(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


def _bool(v) -> bool:
    if isinstance(v, bool):
        return v
    s = str(v).strip().lower()
    if s in ("1", "true", "yes", "on"):
        return True
    if s in ("0", "false", "no", "off"):
        return False
    raise ValueError(f"expected true or false; got {v!r}")


def _floats(v, sep=",") -> List[float]:
    if isinstance(v, (list, tuple)):
        return [float(x) for x in v]
    if isinstance(v, (int, float)):
        return [float(v)]
    return [float(x) for x in str(v).replace(";", sep).split(sep) if x.strip()]


def _polyline(v) -> List[Tuple[float, float]]:
    xs = _floats(v)
    if len(xs) < 4 or len(xs) % 2:
        raise ValueError(
            f"a surface is x0,y0,x1,y1[,x2,y2...] (an even number >= 4 of pixel "
            f"coordinates); got {v!r}"
        )
    return [(xs[k], xs[k + 1]) for k in range(0, len(xs), 2)]


def _surfaces(v):
    if isinstance(v, str):
        if v.strip().lower() == "auto":
            return "auto"
        return [_polyline(p) for p in v.split(";") if p.strip()]
    if isinstance(v, (list, tuple)):
        if v and all(isinstance(x, (int, float)) for x in v):
            return [_polyline(v)]
        return [_polyline(p) for p in v]
    raise ValueError(f"expected 'auto' or a list of polylines; got {v!r}")


def _parsers() -> Dict[str, Any]:
    """Column -> function turning a cell (CSV text or TOML value) into the
    value; an empty CSV cell means "use the default". The config's columns
    are read by the settings table (:func:`qogi.pipeline.settings.from_value`: the
    values and messages of the command line and the settings TOML)."""
    from functools import partial

    p: Dict[str, Any] = {
        "path": str,
        "name": str,
        "surfaces": _surfaces,
        "auto_distances_px": _floats,
        "camera": str,
        "ifov_rad": float,
        "plots": _bool,
        "timeout_s": float,
    }
    for name in _config_fields():
        p[name] = partial(from_value, name)
    return p


def _read_toml(path: pathlib.Path) -> Tuple[dict, List[Tuple[str, dict]]]:
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # the same parser as a package (extra "batch")
        import tomli as tomllib
    try:
        doc = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"manifest {path}: cannot read it ({e})") from e
    except tomllib.TOMLDecodeError as e:
        raise UsageError(f"manifest {path}: not valid TOML ({e})") from e
    unknown = sorted(set(doc) - {"defaults", "recording", "rows"})
    if unknown:
        raise UsageError(
            f"manifest {path}: unknown top-level key(s) {', '.join(unknown)}; a "
            'manifest has [defaults], [[recording]] tables and/or rows = "FILE.csv"'
        )
    defaults = doc.get("defaults", {})
    if not isinstance(defaults, dict):
        raise UsageError(f"manifest {path}: [defaults] must be a table")
    rows = []
    recs = doc.get("recording", [])
    if not isinstance(recs, list):
        raise UsageError(f"manifest {path}: recordings are [[recording]] tables")
    for k, r in enumerate(recs):
        rows.append((f"{path}: [[recording]] #{k + 1}", r))
    if "rows" in doc:
        csv_path = path.parent / str(doc["rows"])
        rows += _read_csv(csv_path)
    return defaults, rows


def _read_csv(path: pathlib.Path) -> List[Tuple[str, dict]]:
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            text = fh.read()
    except (OSError, UnicodeDecodeError) as e:
        raise UsageError(f"manifest {path}: cannot read it ({e})") from e
    lines = text.splitlines(keepends=True)
    # Comment lines (#) are skipped but counted, so messages give file lines.
    numbered = [
        (k + 1, ln) for k, ln in enumerate(lines) if ln.strip() and not ln.lstrip().startswith("#")
    ]
    if not numbered:
        raise UsageError(
            f"manifest {path}: empty; the first line names the columns (at least 'path')"
        )
    reader = csv.reader([ln for _, ln in numbered])
    header = [h.strip() for h in next(reader)]
    rows = []
    for (lineno, _), cells in zip(numbered[1:], reader):
        if len(cells) > len(header):
            raise UsageError(
                f"manifest {path} line {lineno}: {len(cells)} cells but the header "
                f"has {len(header)} columns (quote cells holding commas: "
                '"100,200,220,200")'
            )
        rows.append(
            (
                f"{path} line {lineno}",
                {h: c.strip() for h, c in zip(header, cells) if c.strip() != ""},
            )
        )
    return rows


def load_manifest(path: Union[str, os.PathLike], *, check_files: bool = True) -> List[Row]:
    """Read and validate a manifest (``.csv`` or ``.toml``; docs/batch.md).

    Every row is checked before anything runs: unknown columns, values that
    do not parse, settings :class:`qogi.QuantifyConfig` refuses, missing
    recordings (with ``check_files``), duplicate output names. Relative
    recording paths are taken from the manifest's folder.

    Raises
    ------
    UsageError
        Naming the row (file and line, or ``[[recording]] #N``), the column,
        the value and the fix.
    """

    path = pathlib.Path(path)
    if not path.is_file():
        raise UsageError(f"manifest {path}: no such file")
    suffix = path.suffix.lower()
    if suffix == ".toml":
        defaults, raw = _read_toml(path)
    elif suffix == ".csv":
        defaults, raw = {}, _read_csv(path)
    else:
        raise UsageError(f"manifest {path}: give a .csv or .toml file (docs/batch.md)")
    if not raw:
        raise UsageError(f"manifest {path}: no recordings listed")
    parsers = _parsers()
    known = set(parsers)

    def parse(where: str, values: dict) -> dict:
        out = {}
        for key, v in values.items():
            if key in _RESERVED:
                raise UsageError(f"{where}: column {key!r}: set by qogi batch (use --threads)")
            if key not in known:
                raise UsageError(
                    f"{where}: unknown column {key!r}; known: {', '.join(sorted(known))}"
                )
            try:
                out[key] = parsers[key](v)
            except SettingError as e:
                raise UsageError(f"{where}: column {key!r}: {e.body}") from None
            except (ValueError, TypeError) as e:
                raise UsageError(f"{where}: column {key!r}: cannot use {v!r}: {e}") from None
        return out

    base = parse(f"{path}: [defaults]", defaults)
    if "path" in base or "name" in base:
        raise UsageError(f"{path}: [defaults]: 'path' and 'name' belong to each row")
    fields = _config_fields()
    rows: List[Row] = []
    names: Dict[str, str] = {}
    for where, values in raw:
        v = dict(base)
        v.update(parse(where, values))
        if "path" not in v:
            raise UsageError(f"{where}: column 'path' is missing (the recording file)")
        rec = pathlib.Path(v["path"]).expanduser()
        if not rec.is_absolute():
            rec = path.parent / rec
        if check_files and not rec.is_file():
            raise UsageError(
                f"{where}: column 'path': {rec} does not exist; fix the path "
                "(relative paths start at the manifest's folder)"
            )
        name = v.get("name") or rec.stem
        if not _NAME_RE.match(name):
            raise UsageError(
                f"{where}: column 'name': {name!r} is not a usable folder name; "
                "use letters, digits, '.', '_' and '-'"
            )
        if name in names:
            raise UsageError(
                f"{where}: output name {name!r} is already used by {names[name]}; "
                "give each row its own 'name'"
            )
        names[name] = where
        surfaces = v.get("surfaces")
        if surfaces is None:
            raise UsageError(
                f"{where}: column 'surfaces' is missing: give polylines "
                "x0,y0,x1,y1;... or 'auto' (here or in [defaults])"
            )
        dists = v.get("auto_distances_px")
        if surfaces == "auto" and not dists:
            raise UsageError(
                f"{where}: surfaces 'auto' needs column 'auto_distances_px' (pixel "
                "distances from the source, e.g. 50;100)"
            )
        if dists is not None and any(not (math.isfinite(d) and d > 0) for d in dists):
            raise UsageError(
                f"{where}: column 'auto_distances_px': distances must be > 0 px; got {dists}"
            )
        if v.get("camera") is not None and v["camera"] not in camera_preset_names():
            raise UsageError(
                f"{where}: column 'camera': unknown camera {v['camera']!r}; "
                f"known: {', '.join(camera_preset_names())}"
            )
        if v.get("ifov_rad") is not None and not 0 < v["ifov_rad"] <= 0.1:
            raise UsageError(
                f"{where}: column 'ifov_rad' must be within (0, 0.1] rad; got {v['ifov_rad']}"
            )
        if v.get("timeout_s") is not None and not v["timeout_s"] > 0:
            raise UsageError(f"{where}: column 'timeout_s' must be > 0 s; got {v['timeout_s']}")
        try:
            cfg = QuantifyConfig(**{k: x for k, x in v.items() if k in fields})
        except SettingError as e:
            raise UsageError(f"{where}: column {e.name!r}: {e.body}") from None
        except (ValueError, TypeError) as e:
            col = next((k for k in fields if k in str(e)), None)
            what = f"column {col!r}: " if col else ""
            raise UsageError(f"{where}: {what}{e}") from None
        if check_files:
            _check_scene_facts(where, rec, cfg)
        rows.append(
            Row(
                name=name,
                path=str(rec),
                surfaces=surfaces,
                auto_distances_px=dists if surfaces == "auto" else None,
                config=cfg,
                camera=v.get("camera"),
                ifov_rad=v.get("ifov_rad"),
                plots=bool(v.get("plots", False)),
                timeout_s=v.get("timeout_s"),
                where=where,
            )
        )
    return rows


def _check_scene_facts(where: str, path: pathlib.Path, cfg) -> None:
    """A row whose method needs a scene fact that only the recording can
    give (velocity 'wind' without a wind speed) is checked against the
    recording's /scene now, before anything runs (qogi.pipeline.settings.complete)."""

    if not (cfg.velocity == "wind" and cfg.wind_speed_m_s is None):
        return

    try:
        with open_recording(str(path)) as r:
            scene = r.scene
    except (OSError, ValueError) as e:
        raise UsageError(
            f"{where}: column 'wind_speed_m_s': must be given for velocity='wind' "
            f"(the recording {path.name} cannot be read for its /scene wind speed: {e})"
        ) from None
    try:
        cfg.completed(scene)
    except SettingError as e:
        raise UsageError(f"{where}: column {e.name!r}: {e.body}") from None


# ---------------------------------------------------------------------------
# One recording (runs on a Dask worker)


class _TimedOut(Exception):
    pass


def _cpu_count() -> int:
    from dask.system import CPU_COUNT

    return int(CPU_COUNT)


def _host(address: str) -> str:
    return address.rsplit(":", 1)[0] if address else ""


def _engine_threads(job: dict) -> int:
    """Engine threads for one recording: as asked, else this host's CPUs
    divided among the task slots of all workers on the host (several worker
    processes on one node share its cores), as the scheduler knows them when
    the task starts."""
    if job.get("threads"):
        return int(job["threads"])
    slots = 1
    try:
        from distributed import get_client, get_worker

        worker = get_worker()
        slots = max(1, int(worker.state.nthreads))
        host = _host(worker.address)
        workers = get_client().scheduler_info(n_workers=-1).get("workers", {})
        slots = max(
            slots, sum(int(w.get("nthreads", 1)) for a, w in workers.items() if _host(a) == host)
        )
    except (ImportError, ValueError, AttributeError, OSError):
        pass
    return max(1, _cpu_count() // slots)


def _remove_stale_temporaries(folder: pathlib.Path) -> None:
    """Temporary files left by a killed writer (qogi.files names them so)."""

    for p in glob.glob(str(folder / (_TMP_PREFIX + "*"))):
        try:
            os.unlink(p)
        except OSError:
            pass


def _write_json(path: pathlib.Path, d: dict) -> None:

    with atomic_open(path, "w") as fh:
        fh.write(json.dumps(d, indent=2) + "\n")


def _worker_address() -> str:
    try:
        from distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return ""


def run_row(job: dict) -> dict:
    """Quantify one manifest row and write its outputs; returns its summary row.

    ``job``: ``row`` (:class:`Row`), ``outdir``, ``config_hash``, ``threads``.
    Bad input (a reader or validation error, ``ValueError``/``OSError``) and
    a timeout are recorded in the returned row and ``failure.json``; anything
    else (a bug, memory exhaustion, an output that cannot be written) is
    raised so that Dask's ``retries`` run it again.
    """

    row: Row = job["row"]
    folder = pathlib.Path(job["outdir"]) / row.name
    folder.mkdir(parents=True, exist_ok=True)
    _remove_stale_temporaries(folder)
    meta = {
        "name": row.name,
        "path": row.path,
        "config_hash": job["config_hash"],
        "qogi_version": __version__,
        "worker": _worker_address(),
        "manifest_row": row.where,
    }
    t0, c0 = time.perf_counter(), time.process_time()
    cfg = row.config.replace(num_threads=_engine_threads(job))
    meta["engine_threads"] = cfg.num_threads
    deadline = None if row.timeout_s is None else t0 + row.timeout_s
    stage = {"message": "opening the recording"}

    def progress(fraction: float, message: str):
        stage["message"] = message
        if deadline is not None and time.perf_counter() > deadline:
            return False
        return None

    placed = Diagnostics()
    try:
        with open_recording(row.path) as rec:
            if row.camera is not None or row.ifov_rad is not None:
                _override_camera(rec, row)
            if isinstance(row.surfaces, str):  # "auto": load_manifest gave the distances
                assert row.surfaces == "auto" and row.auto_distances_px is not None
                stage["message"] = "placing surfaces"
                surfaces, source = auto_surfaces(
                    plume_image(rec),
                    row.auto_distances_px,
                    source=cfg.source,
                    return_source=True,
                    warnings=placed,
                )
                if cfg.source is None:
                    cfg.source = source
            else:
                surfaces = [Surface(p, name=f"S{k + 1}") for k, p in enumerate(row.surfaces)]
            if deadline is not None and time.perf_counter() > deadline:
                raise _TimedOut()
            result = quantify(rec, surfaces, cfg, progress=progress, keep_maps=row.plots)
            result.warnings.extend_unique(placed)  # surfaces cut by the image border
    except (Cancelled, _TimedOut):
        return _failed(
            folder,
            meta,
            t0,
            "TimeoutError",
            f"timed out after {row.timeout_s:g} s (timeout_s) while "
            f"{stage['message']}; raise timeout_s or split the recording (frames)",
        )
    except (ValueError, OSError) as e:
        return _failed(folder, meta, t0, type(e).__name__, str(e), traceback.format_exc())
    meta["run_time_s"] = time.perf_counter() - t0
    # The worker process runs one recording at a time: its CPU time is this one's.
    meta["cpu_time_s"] = time.process_time() - c0
    meta["status"] = "ok"
    d = result.to_dict()
    d["batch"] = meta
    if row.plots:
        result.plot(folder / "rates.png", kind="rates")
        if result.map_frames:
            result.plot(folder / "maps.png", kind="maps")
        if result.min_detectable_column_species:
            result.plot(folder / "detectability.png", kind="detectability")
    # Last: an existing result.json means the row's outputs are all there.
    _write_json(folder / RESULT_JSON, d)
    try:
        os.unlink(folder / FAILURE_JSON)
    except FileNotFoundError:
        pass
    return summary_row(d)


def _override_camera(rec, row: Row) -> None:

    cam = rec.camera
    if row.camera is not None:
        preset = camera_preset(row.camera)
        if channel_problem(preset.channels, rec.n_channels) is not None:
            raise UsageError(
                f"camera {row.camera!r} has {len(preset.channels)} channel(s) but "
                f"{row.path} has {rec.n_channels}; choose a camera with as many "
                "channels as the recording"
            )
        cam = dataclasses.replace(
            cam,
            name=preset.name,
            ifov_rad=preset.ifov_rad,
            channels=preset.channels,
            netd_K=preset.netd_K,
        )
    if row.ifov_rad is not None:
        cam = dataclasses.replace(cam, ifov_rad=float(row.ifov_rad))
    cam.validate(row.path)
    rec.camera = cam


def _failed(
    folder: pathlib.Path, meta: dict, t0: float, error_type: str, message: str, tb: str = ""
) -> dict:
    meta = dict(
        meta,
        status="failed",
        error_type=error_type,
        error=message,
        run_time_s=time.perf_counter() - t0,
    )
    _write_json(
        folder / FAILURE_JSON,
        {"format": "qogi-batch-failure", "version": 1, "batch": meta, "traceback": tb},
    )
    return failed_row(meta)


# ---------------------------------------------------------------------------
# The summary table


def summary_row(result: dict) -> dict:
    """One summary row from a result JSON (as written by :func:`run_row`):
    per surface and species the mean and 90 % interval [kg/h] (and the truth
    when the recording has it), the signal-to-noise, the error model's
    expected error and the rate detected with 90 % probability there (the
    operating point), the warnings, the batch metadata."""
    b = result.get("batch", {})
    row = {
        "name": b.get("name"),
        "path": b.get("path"),
        "status": "ok",
        "error_type": "",
        "error": "",
        "complete": bool(result.get("complete", True)),
    }
    for s in result.get("surfaces", []):
        for sp, r in s.get("species", {}).items():
            key = f"{s.get('name') or 'surface'}/{sp}"
            lo, hi = r.get("ci90_kg_h", [None, None])
            row[f"{key} mean_kg_h"] = _num(r.get("mean_kg_h"))
            row[f"{key} ci90_low_kg_h"] = _num(lo)
            row[f"{key} ci90_high_kg_h"] = _num(hi)
            if "truth_kg_h" in r:
                row[f"{key} truth_kg_h"] = _num(r.get("truth_kg_h"))
            # where in the operating envelope, and the rate detected 90 % of the time there
            op = r.get("operating_point") or {}
            row[f"{key} snr"] = _num(op.get("snr"))
            row[f"{key} expected_error"] = _num(op.get("expected_error"))
            row[f"{key} pod_90_kg_h"] = _num(op.get("pod_90_kg_h"))
    warnings = result.get("warnings", [])
    row["n_warnings"] = len(warnings)
    row["warnings"] = " | ".join(_warning_text(w) for w in warnings)
    row.update(_meta_columns(b))
    audit = result.get("audit") or {}
    row.update({k: audit.get(k) or "" for k in _AUDIT_COLUMNS})
    return row


def failed_row(meta: dict) -> dict:
    row = {
        "name": meta.get("name"),
        "path": meta.get("path"),
        "status": "failed",
        "error_type": meta.get("error_type", ""),
        "error": meta.get("error", ""),
        "complete": False,
        "n_warnings": 0,
        "warnings": "",
    }
    row.update(_meta_columns(meta))
    return row


def pending_row(row: Row) -> dict:
    """A row not run (yet): interrupted batch, or still running at a
    periodic summary."""
    r = {
        "name": row.name,
        "path": row.path,
        "status": "not done",
        "error_type": "",
        "error": "",
        "complete": False,
        "n_warnings": 0,
        "warnings": "",
    }
    r.update(_meta_columns({"manifest_row": row.where}))
    return r


def _meta_columns(b: dict) -> dict:
    return {
        "run_time_s": _num(b.get("run_time_s")),
        "cpu_time_s": _num(b.get("cpu_time_s")),
        "engine_threads": int(b.get("engine_threads") or 0),
        "qogi_version": b.get("qogi_version", ""),
        "config_hash": b.get("config_hash", ""),
        "worker": b.get("worker", ""),
        "manifest_row": b.get("manifest_row", ""),
        "reused": bool(b.get("reused", False)),
    }


def _warning_text(w: dict) -> str:
    where = "/".join(x for x in (w.get("surface"), w.get("species")) if x)
    return f"[{w.get('code')}{' ' + where if where else ''}] {w.get('message')}"


def _num(x):
    return float("nan") if x is None else float(x)


#: The audit record's columns of the summary (qogi.audit; the qogi version
#: is the batch's own column); empty for rows that did not run.
_AUDIT_COLUMNS = [
    "recording_sha256",
    "recording_time_utc",
    "run_started_utc",
    "site",
    "component",
    "operator",
    "location",
]
_LEADING = ["name", "path", "status", "error_type", "error", "complete"]
_TRAILING = [
    "n_warnings",
    "warnings",
    "run_time_s",
    "cpu_time_s",
    "engine_threads",
    "qogi_version",
    "config_hash",
    "worker",
    "manifest_row",
    "reused",
] + _AUDIT_COLUMNS


def summary_frame(rows: Sequence[dict]):
    """The summary table (pandas.DataFrame), one row per manifest row in
    manifest order, the per-surface/species columns in between the fixed ones."""
    import pandas as pd

    middle: List[str] = []
    for r in rows:
        for k in r:
            if k not in _LEADING and k not in _TRAILING and k not in middle:
                middle.append(k)
    cols = _LEADING + middle + _TRAILING
    df = pd.DataFrame([{k: r.get(k) for k in cols} for r in rows], columns=cols)
    for k in middle + ["run_time_s", "cpu_time_s"]:
        df[k] = pd.to_numeric(df[k], errors="coerce").astype("float64")
    for k in ("complete", "reused"):
        df[k] = df[k].astype(bool)
    for k in ("n_warnings", "engine_threads"):
        df[k] = pd.to_numeric(df[k], errors="coerce").fillna(0).astype("int64")
    for k in (
        "name",
        "path",
        "status",
        "error_type",
        "error",
        "warnings",
        "qogi_version",
        "config_hash",
        "worker",
        "manifest_row",
        *_AUDIT_COLUMNS,
    ):
        df[k] = df[k].fillna("").astype(str)
    return df


def write_summary(df, outdir: pathlib.Path) -> None:
    """``summary.csv`` and ``summary.parquet`` in ``outdir``, each atomic."""

    with atomic_open(outdir / SUMMARY_CSV, "w", newline="") as fh:
        df.to_csv(fh, index=False)
    with atomic_path(outdir / SUMMARY_PARQUET) as tmp:
        df.to_parquet(tmp, index=False)


def _reusable(
    row: Row, outdir: pathlib.Path, config_hash: str, reused: bool = True
) -> Optional[dict]:
    """The summary row of an existing result with the same config hash."""
    p = outdir / row.name / RESULT_JSON
    try:
        d = json.loads(p.read_text())
    except (OSError, ValueError):
        return None
    b = d.get("batch", {})
    if b.get("config_hash") != config_hash or b.get("status") != "ok":
        return None
    r = summary_row(d)
    r["reused"] = reused
    return r


# ---------------------------------------------------------------------------
# Running


def default_workers(n_jobs: int) -> int:
    """Workers for a LocalCluster: one per CPU, no more than the jobs, and
    about 2 GB of memory each."""
    from dask.system import CPU_COUNT

    try:
        import psutil

        by_memory = max(1, int(psutil.virtual_memory().total // _MEMORY_PER_WORKER))
    except ImportError:
        by_memory = CPU_COUNT
    return max(1, min(CPU_COUNT, max(1, n_jobs), by_memory))


def _has_bokeh() -> bool:
    import importlib.util

    return importlib.util.find_spec("bokeh") is not None


def _dashboard(client) -> Tuple[Optional[str], str]:
    """The dashboard address, or None and why not: the scheduler runs none
    (started with --no-dashboard) or cannot draw it (bokeh missing where the
    scheduler runs: its pages then answer 404)."""
    try:
        services = client.scheduler_info().get("services", {})
        if "dashboard" not in services:
            return None, "the scheduler runs none"
        if not client.run_on_scheduler(_has_bokeh):
            return None, "bokeh is not installed where the scheduler runs (pip install bokeh)"
        return client.dashboard_link, ""
    except (OSError, AttributeError, KeyError, TimeoutError) as e:
        return None, f"cannot ask the scheduler ({e})"


def run(
    manifest: Union[str, os.PathLike],
    outdir: Union[str, os.PathLike],
    *,
    workers: Optional[int] = None,
    threads: Optional[int] = None,
    scheduler: Optional[str] = None,
    resume: bool = False,
    overwrite: bool = False,
    retries: int = 2,
    timeout_s: Optional[float] = None,
    plots: Optional[bool] = None,
    progress: bool = True,
    log=None,
):
    """Quantify every recording of a manifest on Dask; returns the summary
    table (pandas.DataFrame, also written to ``OUTDIR/summary.csv`` and
    ``.parquet``).

    Parameters
    ----------
    manifest : path
        ``.csv`` or ``.toml`` (docs/batch.md); validated whole before anything runs.
    outdir : path
        Output folder: ``<name>/result.json`` (plus plots) per row, the summary.
    workers : int, optional
        Worker processes of the LocalCluster (default: one per CPU, at most
        one per row, ~2 GB of memory each). Each runs one recording at a time.
    threads : int, optional
        Engine threads per recording (default: the CPUs shared among the
        workers, so they do not oversubscribe the machine).
    scheduler : str, optional
        ``tcp://host:port`` of an existing Dask scheduler (then ``workers`` is
        not used; its workers must see the recordings and ``outdir``).
    resume : bool
        Skip rows whose ``result.json`` exists with the same config hash.
    overwrite : bool
        Redo every row although ``outdir`` holds a batch already.
    retries : int
        Dask ``retries=`` of each task (for errors other than bad input) and,
        on a LocalCluster, how often a task may lose its worker.
    timeout_s : float, optional
        Per-recording limit [s] for rows that do not set ``timeout_s``.
    plots : bool, optional
        Write ``rates.png``/``maps.png`` for every row (default: each row's
        ``plots``).
    progress : bool
        Draw the progress bar and messages on stderr.
    log : file, optional
        Where the messages go (default stderr; the bar is always on stderr).

    Raises
    ------
    UsageError
        A bad manifest or argument, an OUTDIR holding a batch without
        ``resume``/``overwrite``, a scheduler that cannot be reached; before
        any recording runs.
    """
    import dask
    from distributed import Client, LocalCluster, as_completed

    say = (
        (lambda msg: print(msg, file=log or sys.stderr, flush=True))
        if progress
        else (lambda msg: None)
    )
    # 1. The manifest, validated whole.
    rows = load_manifest(manifest)
    if retries < 0:
        raise UsageError(f"--retries must be >= 0; got {retries}")
    if workers is not None and workers < 1:
        raise UsageError(f"--workers must be >= 1; got {workers}")
    if threads is not None and threads < 1:
        raise UsageError(f"--threads must be >= 1; got {threads}")
    if timeout_s is not None and not timeout_s > 0:
        raise UsageError(f"--timeout must be > 0 s; got {timeout_s}")
    out = pathlib.Path(outdir)
    if out.exists() and not out.is_dir():
        raise UsageError(f"-o {out}: is a file; give a folder")
    if (out / SUMMARY_CSV).exists() and not (resume or overwrite):
        raise UsageError(
            f"-o {out}: already holds a batch ({SUMMARY_CSV}); give --resume to "
            "continue it (rows done with the same settings are kept) or "
            "--overwrite to redo every row"
        )
    out.mkdir(parents=True, exist_ok=True)

    check_outputs(
        {"summary.csv": out / SUMMARY_CSV, "summary.parquet": out / SUMMARY_PARQUET},
        inputs=[manifest] + [r.path for r in rows],
    )
    for r in rows:
        if timeout_s is not None and r.timeout_s is None:
            r.timeout_s = float(timeout_s)
        if plots is not None:
            r.plots = bool(plots)

    # 2. The jobs: rows not already done.
    results: List[Optional[dict]] = [None] * len(rows)
    hashes = [r.config_hash() for r in rows]
    jobs = []
    for k, (r, h) in enumerate(zip(rows, hashes)):
        done = _reusable(r, out, h) if resume else None
        if done is not None:
            results[k] = done
        else:
            jobs.append(
                (k, {"row": r, "outdir": str(out.resolve()), "config_hash": h, "threads": threads})
            )
    n_reused = len(rows) - len(jobs)
    if resume:
        say(
            f"qogi batch: {n_reused} of {len(rows)} rows already done with the same settings; "
            f"{len(jobs)} to run"
        )

    # 3. The cluster, 4. the tasks, 5. collected as they complete.
    if jobs:
        cluster = None
        if scheduler is None:
            n = workers or default_workers(len(jobs))
            if threads is None:
                threads = max(1, _cpu_count() // n)
                for _, j in jobs:
                    j["threads"] = threads
            with dask.config.set({"distributed.scheduler.allowed-failures": retries}):
                cluster = LocalCluster(
                    n_workers=n,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address="127.0.0.1:0",
                    host="127.0.0.1",
                )
            say(
                f"qogi batch: local cluster of {n} worker(s), {threads} engine thread(s) per "
                f"recording"
            )
        try:
            client = Client(cluster) if cluster is not None else Client(scheduler, timeout=30)
        except (OSError, TimeoutError) as e:
            if cluster is not None:
                cluster.close()
            raise UsageError(
                f"--scheduler {scheduler}: cannot connect ({e}); start it with "
                "`dask scheduler` and check the address"
            ) from None
        try:
            link, why = _dashboard(client)
            say(
                f"qogi batch: Dask dashboard at {link}"
                if link
                else f"qogi batch: Dask dashboard not available: {why}"
            )
            _collect(
                client,
                jobs,
                rows,
                results,
                hashes,
                out,
                retries,
                say,
                progress,
                as_completed,
                ProgressBar,
            )
        except KeyboardInterrupt:
            # What finished is on disk; the summary says what is missing.
            write_summary(_table(rows, results, out, hashes), out)
            raise
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    df = _table(rows, results, out, hashes)
    write_summary(df, out)
    n_ok = int((df["status"] == "ok").sum())
    n_failed = int((df["status"] == "failed").sum())
    say(
        f"qogi batch: {n_ok} ok, {n_failed} failed; summary in {out / SUMMARY_CSV} "
        f"and {SUMMARY_PARQUET}"
    )
    return df


def _table(
    rows: Sequence[Row], results: Sequence[Optional[dict]], out: pathlib.Path, hashes: Sequence[str]
):
    """The summary of every row: collected results, else a result this run
    wrote but did not collect yet (interrupted), else "not done"."""
    table = []
    for row, r, h in zip(rows, results, hashes):
        table.append(
            r if r is not None else _reusable(row, out, h, reused=False) or pending_row(row)
        )
    return summary_frame(table)


def _collect(
    client, jobs, rows, results, hashes, out, retries, say, progress, as_completed, ProgressBar
) -> None:
    import uuid

    token = uuid.uuid4().hex[:8]  # one batch's keys never collide with another's
    keys = [f"qogi-batch-{j['row'].name}-{j['config_hash'][:8]}-{token}-{k}" for k, j in jobs]
    futures = client.map(run_row, [j for _, j in jobs], key=keys, retries=retries, pure=False)
    index = {f.key: (k, j) for f, (k, j) in zip(futures, jobs)}
    bar = ProgressBar("qogi batch ", enabled=progress)
    t0 = time.perf_counter()
    n_ok = n_failed = 0
    last_summary = t0
    try:
        for fut in as_completed(futures):
            k, job = index[fut.key]
            if fut.status == "finished":
                row = fut.result()
            else:
                try:
                    exc = fut.exception()
                except Exception as e:  # noqa: BLE001 - a cancelled future raises its reason
                    exc = e
                meta = {
                    "name": rows[k].name,
                    "path": rows[k].path,
                    "config_hash": job["config_hash"],
                    "qogi_version": __version__,
                    "manifest_row": rows[k].where,
                    "error_type": type(exc).__name__,
                    "error": f"{exc} (retried up to {retries} times)",
                }
                row = failed_row(meta)
            fut.release()
            results[k] = row
            if row["status"] == "ok":
                n_ok += 1
            else:
                n_failed += 1
                say(f"\nqogi batch: {row['name']} failed: {row['error_type']}: {row['error']}")
            done = n_ok + n_failed
            per_h = 3600.0 * done / max(time.perf_counter() - t0, 1e-9)
            bar(
                done / len(jobs),
                f"{n_ok} ok, {n_failed} failed, {len(jobs) - done} remaining, "
                f"{per_h:.0f} recordings/h",
            )
            if time.perf_counter() - last_summary > _SUMMARY_INTERVAL_S:
                write_summary(_table(rows, results, out, hashes), out)
                last_summary = time.perf_counter()
    finally:
        bar.close()
