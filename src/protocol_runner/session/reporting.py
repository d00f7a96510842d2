"""Report triggering: the HTML report rendered from the session's archive at the end of a session."""

from __future__ import annotations

from pathlib import Path

from ..archive.diskfull import DiskFull, is_disk_full, resume_hint

REPORT_NAME = "report.html"


def render_report(session_dir: Path, archive: Path) -> Path:
    """Render the session's report next to its archive; a full disk is a `DiskFull` with the resume hint."""
    from ..report.render import generate_report  # here: only the report step needs jinja and matplotlib
    from ..report.verdicts import record_verdicts

    try:
        record_verdicts(archive)  # /expectations: the declared expectations and their verdicts
        return generate_report(archive, session_dir / REPORT_NAME)
    except OSError as exc:
        if not is_disk_full(exc):
            raise
        where = f"{session_dir / REPORT_NAME} (the archive is complete)"
        raise DiskFull(f"disk full while writing {where}. {resume_hint(session_dir)}") from None
