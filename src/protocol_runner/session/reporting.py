"""The HTML report rendered from the session's archive at the end of a session, after the verdicts and the
model predictions are recorded in the archive."""

from __future__ import annotations

from pathlib import Path

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

REPORT_NAME = "report.html"


def render_report(session_dir: Path, archive: Path) -> Path:
    """Record the verdicts and predictions in the session's archive and render its report next to it; a
    full disk is a `DiskFull` naming what was being written, with the resume hint."""
    from ..report.evaluate import record_verdicts
    from ..report.load import load_report_data
    from ..report.predictions import Prediction, record_predictions
    from ..report.render import render_with_predictions  # here: only the report step needs jinja

    writing = [f"the verdicts into {archive}"]

    def record(made: tuple[Prediction, ...]) -> None:
        writing[0] = f"the predictions into {archive}"
        record_predictions(archive, made)  # /predictions: the declared predictions' numbers
        writing[0] = f"{session_dir / REPORT_NAME} (the archive is complete)"

    try:
        # read once, for the verdicts and the report: recording the verdicts adds /expectations, which the
        # report does not read (it decides them again from the data). Its datasets are not checked again:
        # consolidation has just checked every unit's sha256, covering every byte copied into the archive
        data = load_report_data(archive, verify=False)
        record_verdicts(archive, data)  # /expectations: the declared expectations and their verdicts
        return render_with_predictions(data, session_dir / REPORT_NAME, record=record)  # as --report draws it
    except (OSError, RuntimeError) as exc:  # HDF5 reports some refused writes as RuntimeError
        if not is_disk_full(exc):
            raise
        raise DiskFull(f"disk full while writing {writing[0]}. {resume_hint(session_dir)}") from None
