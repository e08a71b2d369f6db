"""Files out: the result (CSV, JSON, plots, reports) and the frame as shown."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .. import display
from ..export import (
    ExportError,
    check_writable,
    render_frame_rgb,
    report_text,
    write_frame_png,
    write_pdf_report,
    write_plots,
    write_report,
)

__all__ = ["Exporter"]


class Exporter:
    """The Export section. Every export reports what it wrote (and
    remembers the folder) or why it could not."""

    def __init__(self, vm):
        self.vm = vm

    def reset(self, recording) -> None:
        pass

    def _need_result(self) -> bool:
        if self.vm.run.result is None:
            return self.vm.log.error("nothing to export yet: run the quantification first")
        return True

    def _export(self, what: str, fn) -> bool:
        try:
            written = fn()
        except (ExportError, ValueError, OSError) as e:
            return self.vm.log.error(f"could not export the {what}: {e}")
        paths = written if isinstance(written, list) else [written]
        self.vm.log.info(f"{what} written to {', '.join(str(p) for p in paths)}")
        self.vm.store.set_last_dir(Path(paths[0]).parent)
        return True

    def _export_result(self, path, what: str, write) -> bool:
        """The run's result written to ``path`` (checked writable first) by
        ``write(result, path)``."""
        if not self._need_result():
            return False

        def go():
            p = check_writable(path)
            write(self.vm.run.result, str(p))
            return p

        return self._export(what, go)

    def export_csv(self, path) -> bool:
        """The rate time series as CSV (``Result.to_csv``)."""
        return self._export_result(path, "CSV", lambda result, p: result.to_csv(p))

    def export_json(self, path) -> bool:
        """The whole result as JSON (``Result.to_json``)."""
        return self._export_result(path, "JSON", lambda result, p: result.to_json(p))

    def export_plots(self, path) -> bool:
        """The rate plot as PNG (and the maps plot beside it when the run kept maps)."""
        if not self._need_result():
            return False
        run = self.vm.run
        return self._export(
            "plots", lambda: write_plots(run.result, path, maps=run.result_has_maps)
        )

    def frame_picture(self, zoom: int = 3) -> np.ndarray:
        """What the image shows (frame, overlay, surfaces, region, source) as
        uint8 RGB, ``zoom`` times the recording's size."""
        vm = self.vm
        rgba = vm.video.render().copy()
        over = vm.overlay.render()
        if over is not None:
            rgba = display.blend(rgba, over)
        return render_frame_rgb(
            rgba, vm.editor.surfaces, vm.editor.region, zoom=zoom, source=vm.form.source_point()
        )

    def export_frame(self, path) -> bool:
        """The current frame as shown, as PNG."""
        if self.vm.recording is None:
            return self.vm.log.error("open a recording first: there is no frame to save")
        return self._export("frame", lambda: write_frame_png(path, self.frame_picture()))

    def report(self, files=()) -> str:
        vm = self.vm
        return report_text(
            vm.run.result, vm.file.summary, vm.run.result_surfaces, vm.run.result_settings, files
        )

    def export_report(self, path) -> bool:
        """The report of the result: a PDF (``qogi.apps.report``, the same as
        ``qogi quantify --report``) when ``path`` ends in .pdf, else short Markdown."""
        if not self._need_result():
            return False
        if Path(os.fspath(path)).suffix.lower() == ".pdf":
            return self._export(
                "report", lambda: write_pdf_report(self.vm.run.result, path, self.vm.recording)
            )
        return self._export("report", lambda: write_report(path, self.report()))

    def export_all(self, folder, stem: str = "qogi") -> bool:
        """Everything into ``folder``: <stem>.csv (and .summary.csv), .json,
        _rates.png (and _rates_maps.png), _frame.png, _report.md and _report.pdf."""
        if not self._need_result():
            return False
        f = Path(os.fspath(folder)).expanduser()
        if not f.is_dir():
            return self.vm.log.error(f"could not export: the folder {f} does not exist")
        ok = (
            self.export_csv(f / f"{stem}.csv")
            and self.export_json(f / f"{stem}.json")
            and self.export_plots(f / f"{stem}_rates.png")
            and self.export_frame(f / f"{stem}_frame.png")
        )
        if not ok:
            return False
        if not self.export_report(f / f"{stem}_report.pdf"):
            return False
        files = sorted(
            p for p in f.glob(f"{stem}*") if p.suffix in (".csv", ".json", ".png", ".pdf")
        )
        return self._export(
            "report", lambda: write_report(f / f"{stem}_report.md", self.report(files))
        )
