"""Report triggering: the HTML report rendered from the session's archive at the end of a session.

When the analysis workers are running (`workers.AnalysisPool`), the figures not drawn ahead and the model
predictions are made there, at the end: the workers have matplotlib, the figure code and the compiled model
loaded and warm (`worker_start.PRELOADED`, and the figures they drew ahead), and are idle once the last
analyses are done. The session process then only reads, assembles and writes the HTML.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from concurrent.futures import Future
from concurrent.futures import wait as futures_wait
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

if TYPE_CHECKING:
    from ..report.figure_plan import Drawn
    from ..report.model import Configuration, ReportData
    from ..report.predictions import Prediction

REPORT_NAME = "report.html"

Call = Callable[..., "Future[Any] | None"]
"""Runs `fn(*args)` on an analysis worker (`AnalysisPool.call`); None when the workers are not running."""

_WARMING: list[threading.Thread] = []


def start_warm_up(*, drawing: bool = True) -> None:
    """Load what the report needs (jinja2 and the report's modules, the compiled template; with `drawing`
    also the figure canvases and fonts and the compiled model simulation, which the report otherwise has
    drawn and run by the analysis workers) on a background thread, started while the session waits for its
    last analyses: the report at the very end then only reads and assembles. Once per process;
    `render_report` waits for it (the canvases are not shared while it runs). Any failure is left to the
    report, which loads what it needs itself."""
    if not _WARMING:
        thread = threading.Thread(target=_warm_up, args=(drawing,), name="report-warm-up", daemon=True)
        _WARMING.append(thread)
        thread.start()


def _warm_up(drawing: bool) -> None:
    with contextlib.suppress(Exception):
        from ..report import render  # jinja2, the report's modules (no matplotlib: figure_plan.py)

        render.warm_up()
        if drawing:
            from ..report.figures import warm_up as figures
            from ..report.predictions import warm_up as predictions

            figures()
            predictions()


def render_report(
    session_dir: Path,
    archive: Path,
    known: Mapping[str, Configuration] | None = None,
    call: Call | None = None,
    drawing: Sequence[Future[Any]] = (),
) -> Path:
    """Render the session's report next to its archive (`known`: configurations read ahead from exactly
    the groups the archive holds, `session/read_ahead.py`; `call`: runs work on the analysis workers, which
    then draw the figures and compute the predictions; `drawing`: figures being drawn ahead on them, into
    the figure cache, awaited before the report decides what it draws); a full disk is a `DiskFull` with
    the resume hint."""
    for thread in _WARMING:  # first: the report's modules are imported by one thread at a time
        thread.join()
    from ..report.load import load_report_data
    from ..report.render import render_report as render  # here: only the report step needs jinja
    from ..report.verdicts import record_verdicts

    try:
        # read once, for the verdicts and the report: recording the verdicts adds /expectations, which the
        # report does not read (it decides them again from the data). Its datasets are not checked again:
        # consolidation has just checked every unit's sha256, covering every byte copied into the archive
        data = load_report_data(archive, verify=False, known=known)
        with _prompt_thread_switches():
            aside = _OnWorkers(call, archive, data, drawing) if call is not None else None
            if aside is not None:
                # the figures are handed out first and the verdicts written while they are drawn, once the
                # workers have read the archive for the predictions (it is not written while it is read)
                aside.predictions_read()
            record_verdicts(archive, data)  # /expectations: the declared expectations and their verdicts
            # the analyses are done and the other core idle: the figures not drawn ahead on two processes
            return render(
                data,
                session_dir / REPORT_NAME,
                workers=min(2, os.cpu_count() or 1),
                draw=aside.draw if aside is not None else None,
                predicted=aside.predicted if aside is not None else None,
            )
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        where = f"{session_dir / REPORT_NAME} (the archive is complete)"
        raise DiskFull(f"disk full while writing {where}. {resume_hint(session_dir)}") from None


SWITCH_INTERVAL_S = 0.0005


@contextlib.contextmanager
def _prompt_thread_switches() -> Iterator[None]:
    """While the report is made: Python hands its interpreter to a waiting thread after SWITCH_INTERVAL_S
    instead of its default 5 ms. The page renders on this thread while the worker pool's own threads send
    the figures' data to the workers and take their results; at 5 ms each of their turns waited for the
    render's to end, and the workers began drawing 0.06 s after the figures were handed out."""
    previous = sys.getswitchinterval()
    sys.setswitchinterval(min(previous, SWITCH_INTERVAL_S))
    try:
        yield
    finally:
        sys.setswitchinterval(previous)


class _OnWorkers:
    """The report's figures and predictions made by the analysis workers; anything they cannot make (the
    workers are gone) is made by the report itself, as without workers."""

    CHUNKS = 2  # figure jobs: one per worker, the figures dealt alternately (a second round of jobs waited
    # 0.01-0.02 s on its hand-over: four jobs ended 0.02-0.04 s later than two)

    def __init__(
        self, call: Call, archive: Path, data: ReportData, drawing: Sequence[Future[Any]] = ()
    ) -> None:
        from ..report.figure_plan import surely_drawn  # no matplotlib

        self.call = call
        self.archive = archive
        self.data = data
        # first: computed while the figures are handed out (the archive is only read from now on)
        self.predictions = _submit(call, _predictions, archive, data.protocol_text)
        futures_wait(drawing)  # figures being drawn ahead: in the figure cache before it is looked at
        # then the figures the report surely draws, handed out now: before the page is rendered (which
        # holds this process's interpreter while the workers draw), not from the report's figure thread,
        # and before the figure cache is read (a few hundredths of a second, in the figure thread: `draw`)
        self.first = surely_drawn(data)
        self.handed_out: list[Future[Any] | None] | None = (
            self._hand_out(data, self.first) if self.first else []
        )

    def _hand_out(
        self, data: ReportData, task_ids: list[str], chunks_at_most: int = CHUNKS
    ) -> list[Future[Any] | None]:
        from ..report.figure_plan import for_drawing  # no matplotlib

        n = min(chunks_at_most, len(task_ids))
        chunks = [task_ids[i::n] for i in range(n)]
        return [_submit(self.call, _draw, for_drawing(data, chunk), chunk) for chunk in chunks if chunk]

    def draw(self, data: ReportData, task_ids: list[str]) -> list[Drawn] | None:
        """The figures `task_ids` of `data` (those the report found neither drawn ahead nor in the figure
        cache): the jobs handed out at the start, and the rest (configuration figures whose cache entry
        held other data) handed out now."""
        futures, self.handed_out = self.handed_out, None
        first = set(self.first)
        if futures is None or data is not self.data or not first <= set(task_ids):
            futures = self._hand_out(data, task_ids)  # not what was handed out (once) at the start
        else:
            rest = [figure_id for figure_id in task_ids if figure_id not in first]
            if rest:
                futures = futures + self._hand_out(data, rest, chunks_at_most=2)
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
