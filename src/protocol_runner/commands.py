"""The CLI's actions beyond planning: run, resume, report, hardware check.

Each returns the process exit status; user mistakes raise `UserError` subclasses.
"""

from __future__ import annotations

from pathlib import Path

from .errors import InvalidInput


def run(
    protocol: str,
    *,
    dry_run: bool,
    session: Path | None,
    seed: int | None,
    yes: bool,
    only: list[int] | None,
    realtime: bool,
) -> int:
    raise InvalidInput("running a protocol is not implemented yet (the session engine lands in issue #5)")


def resume(session_dir: Path, *, yes: bool, force: bool, realtime: bool) -> int:
    raise InvalidInput("--resume is not implemented yet (the session engine lands in issue #5)")


def report(
    path: Path,
    *,
    output: Path | None,
    reprocess: bool,
    protocol_file: str | None,
    export_mat: Path | None,
) -> int:
    raise InvalidInput("--report is not implemented yet (the report lands in issue #6)")


def hardware_check(protocol: str | None) -> int:
    raise InvalidInput("--hardware-check is not implemented yet (the USB drivers land in issue #7)")
