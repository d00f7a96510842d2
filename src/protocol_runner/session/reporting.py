"""The HTML report rendered from the session's archive at the end of a session. When the analysis
workers are running, they draw the figures and compute the predictions: the session process then never
loads the drawing library.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from concurrent.futures import Future
from concurrent.futures import wait as futures_wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

if TYPE_CHECKING:
    from ..report.figure_plan import Drawn
    from ..report.model import ReportData
    from ..report.predictions import Prediction

REPORT_NAME = "report.html"

Call = Callable[..., "Future[Any] | None"]
"""Runs `fn(*args)` on an analysis worker (`AnalysisPool.call`); None when the workers are not running."""


def render_report(session_dir: Path, archive: Path, call: Call | None = None) -> Path:
    """Render the session's report next to its archive (`call`: runs work on the analysis workers, which
    then draw the figures and compute the predictions); a full disk is a `DiskFull` with the resume hint."""
    from ..report.evaluate import record_verdicts
    from ..report.load import load_report_data
    from ..report.predictions import record_predictions
    from ..report.render import render_report as render  # here: only the report step needs jinja

    try:
        # read once, for the verdicts and the report: recording the verdicts adds /expectations, which the
        # report does not read (it decides them again from the data). Its datasets are not checked again:
        # consolidation has just checked every unit's sha256, covering every byte copied into the archive
        data = load_report_data(archive, verify=False)
        aside = _OnWorkers(call, archive, data) if call is not None else None
        if aside is not None:
            # the figures are handed out first and the verdicts written while they are drawn, once the
            # workers have read the archive for the predictions (it is not written while it is read)
            aside.predictions_read()
        try:
            record_verdicts(archive, data)  # /expectations: the declared expectations and their verdicts
            made = aside.predicted() if aside is not None else _predictions(archive, data.protocol_text)
            record_predictions(archive, made)  # /predictions: the declared predictions' numbers
        except (OSError, RuntimeError) as exc:  # HDF5 reports some refused writes as RuntimeError
            if not is_disk_full(exc):
                raise
            what = f"the verdicts and predictions into {archive}"
            raise DiskFull(f"disk full while saving {what}. {resume_hint(session_dir)}") from None
        return render(
            data,
            session_dir / REPORT_NAME,
            workers=min(2, os.cpu_count() or 1),
            draw=aside.draw if aside is not None else None,
            predicted=lambda: made,
        )
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        where = f"{session_dir / REPORT_NAME} (the archive is complete)"
        raise DiskFull(f"disk full while writing {where}. {resume_hint(session_dir)}") from None


class _OnWorkers:
    """The report's figures and predictions made by the analysis workers; anything they cannot make (the
    workers are gone) is made by the report itself, as without workers."""

    CHUNKS = 2  # figure jobs: one per worker, the figures dealt alternately

    def __init__(self, call: Call, archive: Path, data: ReportData) -> None:
        from ..report.figure_plan import figure_ids  # no matplotlib

        self.call = call
        self.archive = archive
        self.data = data
        self.predictions = _submit(call, _predictions, archive, data.protocol_text)
        # every figure handed out now, drawn while this process writes the verdicts and renders the page
        self.every = figure_ids(data)
        self.handed_out: list[Future[Any] | None] | None = self._hand_out(data, self.every)

    def _hand_out(self, data: ReportData, task_ids: list[str]) -> list[Future[Any] | None]:
        from ..report.figure_plan import for_drawing  # no matplotlib

        n = min(self.CHUNKS, len(task_ids))
        chunks = [task_ids[i::n] for i in range(n)]
        return [_submit(self.call, _draw, for_drawing(data, chunk), chunk) for chunk in chunks if chunk]

    def draw(self, data: ReportData, task_ids: list[str]) -> list[Drawn] | None:
        """The figures `task_ids` of `data`: the jobs handed out at the start when they are those asked for,
        else handed out now."""
        futures, self.handed_out = self.handed_out, None
        if futures is None or data is not self.data or task_ids != self.every:
            futures = self._hand_out(data, task_ids)
        drawn: list[Drawn] = []
        for future in futures:
            if future is None:
                return None
            try:
                drawn.extend(future.result())
            except BrokenProcessPool:
                return None
        return drawn

    def predictions_read(self) -> None:
        """Wait until the workers' predictions have read the archive (done or failed): it may be written
        to from then on."""
        if self.predictions is not None:
            futures_wait([self.predictions])

    def predicted(self) -> tuple[Prediction, ...]:
        if self.predictions is not None:
            with contextlib.suppress(BrokenProcessPool):
                return self.predictions.result()
        return _predictions(self.archive, self.data.protocol_text)


# what the workers run, named here so that the session never imports the drawing code or the model to name it


def _draw(data: ReportData, task_ids: list[str]) -> list[Drawn]:
    from ..report.figures import draw_figures

    return draw_figures(data, task_ids)


def _predictions(archive: Path, protocol_text: str) -> tuple[Prediction, ...]:
    from ..report.predictions import predictions

    return predictions(archive, protocol_text)


def _submit(call: Call, fn: Callable[..., Any], *args: object) -> Future[Any] | None:
    try:
        return call(fn, *args)
    except (BrokenProcessPool, RuntimeError):  # the workers are gone or shut down
        return None
