"""Report triggering: the HTML report rendered from the session's archive at the end of a session."""

from __future__ import annotations

from pathlib import Path

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

REPORT_NAME = "report.html"


def render_report(session_dir: Path, archive: Path) -> Path:
    """Render the session's report next to its archive; a full disk is a `DiskFull` with the resume hint."""
    from ..report.load import load_report_data
    from ..report.render import render_report as render  # here: only the report step needs jinja, matplotlib
    from ..report.verdicts import record_verdicts

    try:
        # read once, for the verdicts and the report: recording the verdicts adds /expectations, which the
        # report does not read (it decides them again from the data). Its checksums are not read again:
        # consolidation has just checked every unit's sha256, covering every byte copied into the archive
        data = load_report_data(archive, verify=False)
        record_verdicts(archive, data)  # /expectations: the declared expectations and their verdicts
        return render(data, session_dir / REPORT_NAME)
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        where = f"{session_dir / REPORT_NAME} (the archive is complete)"
        raise DiskFull(f"disk full while writing {where}. {resume_hint(session_dir)}") from None
