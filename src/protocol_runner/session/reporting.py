"""Report triggering: the HTML report rendered from the session's archive at the end of a session."""

from __future__ import annotations

import contextlib
import os
import threading
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

if TYPE_CHECKING:
    from ..report.model import Configuration

REPORT_NAME = "report.html"

_WARMING: list[threading.Thread] = []


def start_warm_up() -> None:
    """Load what the report needs (jinja2, matplotlib and the report's modules, the figure canvases and
    fonts, the compiled model simulation) on a background thread, started while the session waits for its
    last analyses: the report at the very end then only reads and assembles. Once per process;
    `render_report` waits for it (the canvases are not shared while it runs). Any failure is left to the
    report, which loads what it needs itself."""
    if not _WARMING:
        thread = threading.Thread(target=_warm_up, name="report-warm-up", daemon=True)
        _WARMING.append(thread)
        thread.start()


def _warm_up() -> None:
    with contextlib.suppress(Exception):
        from ..report import render  # jinja2, matplotlib, the figures
        from ..report.figures import warm_up as figures
        from ..report.predictions import warm_up as predictions

        render.warm_up()
        figures()
        predictions()


def render_report(session_dir: Path, archive: Path, known: Mapping[str, Configuration] | None = None) -> Path:
    """Render the session's report next to its archive (`known`: configurations read ahead from exactly
    the groups the archive holds, `session/read_ahead.py`); a full disk is a `DiskFull` with the resume hint."""
    for thread in _WARMING:  # first: the report's modules are imported by one thread at a time
        thread.join()
    from ..report.load import load_report_data
    from ..report.render import render_report as render  # here: only the report step needs jinja, matplotlib
    from ..report.verdicts import record_verdicts

    try:
        # read once, for the verdicts and the report: recording the verdicts adds /expectations, which the
        # report does not read (it decides them again from the data). Its datasets are not checked again:
        # consolidation has just checked every unit's sha256, covering every byte copied into the archive
        data = load_report_data(archive, verify=False, known=known)
        record_verdicts(archive, data)  # /expectations: the declared expectations and their verdicts
        # the analyses are done and the other core idle: the figures not drawn ahead on two processes
        return render(data, session_dir / REPORT_NAME, workers=min(2, os.cpu_count() or 1))
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        where = f"{session_dir / REPORT_NAME} (the archive is complete)"
        raise DiskFull(f"disk full while writing {where}. {resume_hint(session_dir)}") from None
