"""The package's Python interface (docs/api.md): what `run-protocol` does, as functions.

`load_protocol`, `run`, `open_archive`, `write_report` and `export` are thin wrappers over the command
line's own actions (`commands.py`), re-exported by `protocol_runner` (the report's writer is not called
`report`: `protocol_runner.report` is the subpackage that draws it). Each imports what it needs when called, so
`import protocol_runner` stays cheap. User mistakes raise `protocol_runner.errors.UserError` subclasses
(`InvalidInput` for a bad protocol file, argument or archive) whose `message` is what the command prints.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .protocol.loaded import LoadedProtocol
    from .protocol.only import KeySelection
    from .report.model import ReportData
    from .session.runner import RunResult


def load_protocol(protocol: str | Path) -> LoadedProtocol:
    """Read and check a protocol file as `run-protocol --validate` does (every check a run makes before it
    creates a session; warnings are printed on standard error). `protocol` is a path, or a bare file name
    looked up in `./protocols/` and then among the shipped protocols. Returns the validated protocol
    (`.protocol` the model, `.path`, `.sha256`)."""
    from .commands import preflighted

    return preflighted(str(protocol))[0]


def run(
    protocol: LoadedProtocol | str | Path,
    session: str | Path | None = None,
    *,
    dry_run: bool = True,
    seed: int = 0,
    only: str | Iterable[int] | None = None,
    realtime: bool = False,
    yes: bool = False,
    quiet: bool = True,
) -> RunResult:
    """Run a protocol into the new session directory `session` (default `sessions/<name>-<UTC time>/`):
    a dry run against the simulator (`dry_run=True`, the default; `seed` seeds its random draws) or, with
    `dry_run=False`, a run on the rig's boards (`yes=True` answers the operator checklists). `only` picks
    configuration keys ("4,5,6,7", "12-14" or a list of ints). `quiet=False` shows the progress on standard
    error. Returns the outcome: `.status` ("complete", ...), `.archive` and `.report` (paths)."""
    from .commands import run_loaded

    loaded = protocol if not isinstance(protocol, str | Path) else load_protocol(protocol)
    return run_loaded(
        loaded,
        dry_run=dry_run,
        session=None if session is None else Path(session),
        seed=seed,
        yes=yes,
        only=_keys(only),
        realtime=realtime,
        quiet=quiet,
    )


def open_archive(path: str | Path) -> ReportData:
    """An archive (or a session directory holding `archive.h5`) read into the report's data model, every
    dataset checked against its checksum first: `.session` (protocol, seed, status, ...) and
    `.configurations`, each with its `.key`, `.settings`, `.trials` and per-cycle `.energy_loss_j`
    (docs/report.md and docs/archive.md describe the fields)."""
    from .report.load import load_report_data

    return load_report_data(Path(path), workers=1)


def write_report(path: str | Path, output: str | Path | None = None) -> Path:
    """Write the HTML report of an archive or session directory (default `report.html` beside the archive,
    as `run-protocol --report`); returns its path. A session without an archive yet is consolidated first."""
    from .commands import _archive_of, _html_output
    from .report.render import generate_report

    out = None if output is None else Path(output)
    _html_output(out)
    return generate_report(_archive_of(Path(path)), out)


def export(
    path: str | Path, output: str | Path | None = None, *, only: str | Iterable[int] | None = None
) -> tuple[Path, ...]:
    """Write `cycles.csv`, `trials.csv` and `configurations.csv` of an archive or session directory into
    the directory `output` (default `tables/` beside the archive), as `run-protocol --export [--only]`;
    returns the three paths."""
    from .commands import _archive_of
    from .report.tidy import export_tables

    archive = _archive_of(Path(path))
    out_dir = Path(output) if output is not None else archive.parent / "tables"
    return export_tables(archive, out_dir, only=_keys(only))


def _keys(only: str | Iterable[int] | None) -> KeySelection | None:
    from .protocol.only import KeySelection

    if only is None:
        return None
    return KeySelection.parse(only if isinstance(only, str) else ",".join(str(int(k)) for k in only))
