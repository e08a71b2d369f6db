"""The quantification run and the result it returned."""

from __future__ import annotations

from typing import List

from .. import results
from ..jobs import CANCELLED, DONE, Job
from ..settings import SettingsError
from ..surfaces import SurfaceDraft

__all__ = ["RunPanel"]


class RunPanel:
    """Starting ``qogi.quantify`` in the background with the drawn surfaces and
    the form's config, and holding its result (or the partial result of a
    cancelled run) with the surfaces and settings it was made with."""

    def __init__(self, vm):
        self.vm = vm
        self.result = None
        self.result_partial = False
        self.result_surfaces: List[SurfaceDraft] = []
        self.result_settings: dict = {}
        self.result_has_maps = False
        self.result_stale = False
        self._pending: tuple = ([], {}, False)

    def reset(self, recording) -> None:
        self.result, self.result_partial, self.result_stale = None, False, False
        self.result_surfaces, self.result_settings = [], {}

    def inputs_changed(self) -> None:
        """Surfaces or settings changed: a result on screen no longer matches them."""
        if self.result is not None:
            self.result_stale = True

    def start_run(self) -> bool:
        """Check everything, then run ``qogi.quantify`` in the background."""
        vm = self.vm
        error = vm.log.error
        if vm.recording is None:
            return error("open a recording (or the demo) first")
        if vm.work.busy:
            return error(f"the {vm.work.job.name} is already running")
        editor, form = vm.editor, vm.form
        if editor.drawing is not None:
            editor.finish_drawing()
        if not editor.surfaces:
            return error(
                "draw at least one control surface across the plume "
                "(Surfaces: line or polyline) before running"
            )
        try:
            kwargs = form.settings.config_kwargs(vm.api, vm.recording, editor.region)
            config = form.settings.build_config(vm.api, vm.recording, editor.region)
        except SettingsError as e:
            form.field_errors = dict.fromkeys(form.field_errors, "") | e.errors
            return error(f"fix the analysis settings first: {e}")
        try:
            surfaces = [vm.api.Surface(list(s.points), name=s.name) for s in editor.surfaces]
        except (ValueError, TypeError) as e:
            return error(f"a control surface is not valid: {e}")
        form.field_errors = {}
        rec, keep = vm.recording, bool(form.settings.keep_maps)
        api = vm.api

        def work(progress):
            return api.quantify(rec, surfaces, config, progress=progress, keep_maps=keep)

        self._pending = (
            [SurfaceDraft(s.name, list(s.points), s.colour) for s in editor.surfaces],
            kwargs,
            keep,
        )
        vm.work.start(
            Job("quantification", work, cancelled_types=(api.Cancelled,)),
            "quantify",
            self._finished,
        )
        vm.log.info(
            f"quantifying {', '.join(kwargs['species'])} through {len(surfaces)} surface(s)..."
        )
        return True

    def _finished(self, job: Job, snap: dict) -> None:
        log = self.vm.log
        surfaces, kwargs, keep = self._pending
        if snap["state"] == DONE:
            self._take_result(job.value, surfaces, kwargs, keep, partial=False)
            log.info(f"quantification finished in {snap['elapsed_s']:.1f} s")
        elif snap["state"] == CANCELLED:
            if job.partial is not None:
                self._take_result(job.partial, surfaces, kwargs, keep, partial=True)
                n = max((r.n_frames for r in results.rate_rows(job.partial)), default=0)
                log.warn(
                    f"quantification cancelled; showing the partial result of the "
                    f"{n} frame(s) finished"
                )
            else:
                log.warn("quantification cancelled before any frame finished")
        else:
            self.vm.work.report_failure("the quantification", job)

    def _take_result(self, result, surfaces, kwargs, keep_maps: bool, partial: bool) -> None:
        self.result, self.result_partial, self.result_stale = result, partial, False
        self.result_surfaces, self.result_settings = surfaces, kwargs
        self.result_has_maps = keep_maps
        self.vm.overlay.new_result()
        species = self.result_species()
        display = self.vm.video.display
        if species and display.overlay_species not in species:
            display.overlay_species = species[0]
        self.vm.rev["result"] += 1

    def result_species(self) -> List[str]:
        """The species of the result, in order of first appearance."""
        if self.result is None:
            return []
        seen = []
        for sr in self.result.surfaces:
            for sp in sr.species:
                if sp not in seen:
                    seen.append(sp)
        return seen
