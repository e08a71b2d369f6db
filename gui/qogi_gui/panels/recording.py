"""Opening recordings: files, camera files (with the scene-facts form) and the
demo scene; the recording's description."""

from __future__ import annotations

import os
from typing import Callable, List, Optional, Tuple

from qogi.errors import UsageError

from ..jobs import CANCELLED, DONE, Job

__all__ = ["RecordingPanel"]


class RecordingPanel:
    """The Recording tab: what is open and how it was opened.

    ``demo_provider(progress) -> path`` makes (or finds) the demo recording."""

    def __init__(self, vm, demo_provider: Callable):
        self.vm = vm
        self.demo_provider = demo_provider
        self.path: Optional[str] = None
        #: A camera file waiting for its scene facts (the form), or None.
        self.scene_request = None
        self.summary: Optional[dict] = None
        self._opening = ""

    def reset(self, recording) -> None:
        pass  # set by set_recording itself

    # ----------------------------------------------------------------- open
    def open(self, path, background: bool = False) -> bool:
        """Open a recording file (validated by ``qogi.open_recording``).

        With ``background`` the file is opened and checked in a worker thread
        (large files are scanned for NaN on open) and shown once
        :meth:`ViewModel.poll` sees it done; the window keeps drawing meanwhile."""
        vm = self.vm
        if vm.work.busy:
            return vm.log.error(
                f"the {vm.work.job.name} is still running: cancel it or wait "
                "before opening another recording"
            )
        p = os.path.abspath(os.path.expanduser(os.fspath(path))) if str(path).strip() else ""
        if not p:
            return vm.log.error("no file chosen: pick a recording (.h5) or a camera file to open")
        facts = self._scene_facts(p)
        if facts is None:
            return False
        if background:
            self._opening = p
            vm.work.start(
                Job("opening the recording", lambda progress: self._open_file(p, facts)),
                "open",
                self._open_finished,
            )
            return True
        try:
            rec, warning = self._open_file(p, facts)
        except (ValueError, OSError) as e:
            return self._open_failed(p, e)
        return self._opened(rec, p, warning)

    def _open_finished(self, job: Job, snap: dict) -> None:
        if snap["state"] == DONE:
            self._opened(job.value[0], self._opening, job.value[1])
        elif isinstance(job.error, (ValueError, OSError)):
            self._open_failed(self._opening, job.error)
        else:
            self.vm.work.report_failure("opening the recording", job)

    def _open_file(self, p: str, facts: Optional[dict] = None):
        """(recording, warning) of the file ``p``; NaN pixels become invalid pixels."""
        api = self.vm.api
        if facts:
            return api.open_recording(p, **facts), ""
        try:
            return api.open_recording(p), ""
        except api.RecordingError as e:
            if "non-finite" not in str(e) or getattr(e, "location", "") != "/frames":
                raise
        rec = api.open_recording(p, nonfinite="invalid")
        return rec, (
            f"{rec.n_invalid} non-finite pixel values in {p} are treated as invalid "
            "pixels (shown transparent, not quantified)"
        )

    def _opened(self, rec, p: str, warning: str) -> bool:
        vm = self.vm
        self.set_recording(rec, p)
        if warning:
            vm.log.warn(warning)
        for d in getattr(rec, "warnings", None) or ():
            vm.log.warn(str(d))
        vm.store.add_recent(p)
        if vm.store.warning:
            vm.log.warn(vm.store.warning)
        vm.log.info(
            f"opened {p}: {rec.n_frames} frames x {rec.n_channels} channel(s), "
            f"{rec.width}x{rec.height} px, {rec.camera.frame_rate_hz:g} Hz"
        )
        return True

    def _open_failed(self, path: str, e: Exception) -> bool:
        vm = self.vm
        if not os.path.exists(path):
            vm.store.remove_recent(path)
        elif isinstance(e, UsageError) and self.scene_request is None:
            # A camera file whose remembered facts no longer fit (e.g. a camera
            # whose band is not the file's): ask again, saying why.
            from qogi.io.open import scene_needs

            try:
                self._ask_scene(
                    path,
                    scene_needs(path),
                    vm.store.scene_for(path) or {},
                    error=f"could not open {os.path.basename(path)}: {e}",
                )
                return False
            except (ValueError, OSError):
                pass
        return vm.log.error(f"could not open the recording: {e}")

    def set_recording(self, rec, path: str = "") -> None:
        """Show the opened ``qogi.Recording`` ``rec`` (also for scripts and
        tests): every panel starts afresh on it."""
        vm = self.vm
        path = path or getattr(rec, "path", "")
        if vm.recording is not None and vm.recording is not rec:
            try:
                vm.recording.close()
            except Exception:  # noqa: BLE001 - closing a file we are done with must not stop the new one
                pass
        vm.recording, self.path = rec, path
        self.summary = rec.summary()
        for panel in vm.panels():
            panel.reset(rec)
        for k in vm.rev:
            vm.rev[k] += 1

    # ----------------------------------------------------------------- camera files
    def _scene_facts(self, p: str):
        """Keyword arguments for opening ``p``: {} for a recording, the facts
        remembered for a camera file, or None when the form must ask for them
        (:attr:`scene_request` is then set)."""
        from qogi.io.open import file_kind, scene_needs

        if not os.path.isfile(p) or file_kind(p) not in ("flir", "telops"):
            return {}
        stored = self.vm.store.scene_for(p)
        try:
            needs = scene_needs(p)
        except (ValueError, OSError) as e:
            self._open_failed(p, e)
            return None
        if stored and all(k in stored for k in needs["needs"]):
            return dict(stored)
        self._ask_scene(p, needs, stored or {})
        return None

    def _ask_scene(self, p: str, needs: dict, values: dict, error: str = "") -> None:
        from ..scene_form import FIELDS, SceneRequest

        self.scene_request = SceneRequest(
            path=p,
            kind=needs["kind"],
            needs=list(needs["needs"]),
            holds=dict(needs["holds"]),
            defaults=list(needs["defaults"]),
            values={k: "" if values.get(k) is None else str(values.get(k)) for k in FIELDS},
            error=error,
        )
        self.vm.rev["scene_request"] += 1
        missing = ", ".join(FIELDS[k][0] for k in needs["needs"])
        if error:
            self.vm.log.error(error)
        else:
            self.vm.log.info(
                f"{os.path.basename(p)} is a camera file: give the scene facts it "
                f"does not hold ({missing}) in the form"
            )

    def submit_scene(self, values: dict) -> bool:
        """Open the pending camera file with the form's ``values`` (text per
        field); remember them for the file when it opens."""
        from ..scene_form import parse_facts

        vm, req = self.vm, self.scene_request
        if req is None:
            return vm.log.error("no camera file is waiting for scene facts")
        req.values.update({k: str(v) for k, v in values.items()})
        facts, errors = parse_facts(req.values, req.needs)
        req.errors = errors
        if errors:
            req.error = "; ".join(errors.values())
            vm.rev["scene_request"] += 1
            return vm.log.error(f"fix the scene facts first: {req.error}")
        try:
            rec, warning = self._open_file(req.path, facts)
        except (ValueError, OSError) as e:
            req.error = str(e)
            vm.rev["scene_request"] += 1
            return vm.log.error(f"could not open {os.path.basename(req.path)}: {e}")
        self.scene_request = None
        vm.rev["scene_request"] += 1
        vm.store.set_scene(req.path, facts)
        return self._opened(rec, req.path, warning)

    def cancel_scene(self) -> None:
        """Close the scene form without opening the file."""
        self.scene_request = None
        self.vm.rev["scene_request"] += 1

    # ----------------------------------------------------------------- demo
    def open_demo(self) -> bool:
        """Open the demo scene: synthesised once (in the background, with
        progress) and then reused from the user's cache."""
        vm = self.vm
        if vm.work.busy:
            return vm.log.error(f"the {vm.work.job.name} is still running: cancel it or wait")
        vm.work.start(Job("demo scene", self.demo_provider), "demo", self._demo_finished)
        vm.log.info("preparing the demo scene...")
        return True

    def _demo_finished(self, job: Job, snap: dict) -> None:
        if snap["state"] == DONE:
            self.open(job.value)
        elif snap["state"] == CANCELLED:
            self.vm.log.warn("the demo scene was not made (cancelled)")
        else:
            self.vm.work.report_failure("making the demo scene", job)

    # ----------------------------------------------------------------- description
    def metadata_rows(self) -> List[Tuple[str, str]]:
        """(label, value) pairs describing the open recording."""
        s = self.summary
        if not s:
            return []
        cam, fr, sc = s["camera"], s["frames"], s["scene"]
        rows = [
            ("file", str(s["path"])),
            ("camera", str(cam["name"])),
            ("pixel field of view", f"{cam['ifov_rad'] * 1e3:.4g} mrad"),
            ("frame rate", f"{cam['frame_rate_hz']:.4g} Hz"),
            ("NETD", f"{cam['netd_K'] * 1e3:.3g} mK" if cam.get("netd_K") else "-"),
            ("frames", f"{fr['T']} x {fr['C']} channel(s) x {fr['W']}x{fr['H']} px"),
            ("duration", f"{fr['duration_s']:.3f} s"),
            ("stored quantity", f"{fr['quantity']} [{fr['unit']}]"),
        ]
        for ch in s["channels"]:
            lo, hi = ch["half_max_cm1"]
            rows.append(
                (
                    f"channel {ch['index']}",
                    f"{ch['name']}: {1e4 / hi:.3f}-{1e4 / lo:.3f} um (half max), "
                    f"centroid {ch['centroid_um']:.3f} um",
                )
            )
        rows += [
            ("distance", f"{sc['distance_m']:g} m"),
            ("ambient temperature", f"{sc['ambient_temperature_K']:.2f} K"),
            ("pressure", f"{sc['pressure_Pa']:.0f} Pa"),
        ]
        for key, label, unit in (
            ("wind_speed_m_s", "wind speed", "m/s"),
            ("gas_temperature_K", "gas temperature", "K"),
            ("background_temperature_K", "background temperature", "K"),
        ):
            if sc.get(key) is not None:
                rows.append((label, f"{sc[key]:g} {unit}"))
        if sc.get("species"):
            rows.append(("species", ", ".join(sc["species"])))
        if fr.get("n_invalid"):
            rows.append(("invalid pixel values", str(fr["n_invalid"])))
        truth = s.get("truth")
        if truth:
            for sp, v in truth["emission_rate_kg_h"].items():
                rows.append((f"true {sp} rate", f"{v:.4g} kg/h"))
        return rows
