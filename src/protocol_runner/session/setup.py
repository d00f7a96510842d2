"""The session directory: a self-contained record of one campaign run.

    <session>/session.json        mode, seed, protocol name and sha256 (and each referenced file's), creation
                                  time, --only; checked field by field when read (session/info_check.py)
    <session>/protocol/           the protocol file exactly as run, plus the files it references
    <session>/journal.jsonl       completed units and events (session/journal.py)
    <session>/units/*.h5          one atomic HDF5 file per finished step (archive/units.py)
    <session>/session.log         the run's log
    <session>/archive.h5          the consolidated archive (at the end, and at every stop)
    <session>/report.html         the report

Resume re-expands the protocol stored here, so it works even if the original file moved or changed.
"""

from __future__ import annotations

import dataclasses
import json
import os
import shutil
from dataclasses import asdict, dataclass, field
from datetime import UTC, datetime
from pathlib import Path

from .. import __version__
from ..archive.diskfull import creates_session_directory
from ..archive.units import fsync_path, sha256_of
from ..errors import InvalidInput
from ..protocol.loaded import LoadedProtocol
from ..protocol.loader import load_protocol
from ..protocol.paths import is_stored_with_session
from ..protocol.plan import expand
from ..protocol.plan_steps import Plan
from ..protocol.rig_file import is_rig_path
from ..protocol.trajectory_specs import FileSpec

SESSION_FILE = "session.json"


@dataclass(frozen=True)
class SessionInfo:
    protocol_name: str
    protocol_sha256: str
    protocol_file: str  # relative to the session directory
    original_path: str
    mode: str  # "dry-run" / "hardware"
    seed: int
    created_utc: str
    only: tuple[int, ...]
    software_version: str
    realtime: bool = False
    # every file the protocol references, as copied into <session>/protocol/: relative path -> sha256
    files_sha256: dict[str, str] = field(default_factory=dict)
    # sha256 of the rig file the protocol was checked against (a shipped rig may change with an upgrade;
    # a rig file beside the protocol is copied into <session>/protocol/ and listed in files_sha256 too)
    rig_sha256: str = ""

    def to_json(self) -> str:
        d = asdict(self)
        d["only"] = list(self.only)
        return json.dumps(d, indent=2)


def default_session_dir(protocol_name: str, cwd: Path | None = None) -> Path:
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return (cwd or Path.cwd()) / "sessions" / f"{protocol_name}-{stamp}"


def referenced_files(loaded: LoadedProtocol) -> list[str]:
    p = loaded.protocol
    files = [spec.file for spec in p.trajectories.values() if isinstance(spec, FileSpec)]
    files += [
        f
        for f in (
            p.rig.calibration.command_table,
            p.rig.calibration.angle_table,
            p.rig.calibration.torque_table,
        )
        if f
    ]
    if p.report.reference_dataset:
        files.append(p.report.reference_dataset)
    if is_rig_path(p.rig_name):  # a lab's own rig file beside the protocol: the session keeps its copy
        files.append(p.rig_name)
    return files


@creates_session_directory  # a full disk or a write error leaves no half-made session behind
def create_session(
    directory: Path, loaded: LoadedProtocol, *, mode: str, seed: int, only: tuple[int, ...], realtime: bool
) -> SessionInfo:
    if directory.exists() and not directory.is_dir():
        raise InvalidInput(f"--session {directory}: is a file, not a directory")
    if (directory / SESSION_FILE).exists():
        raise InvalidInput(
            f"{directory} already holds a session; continue it with: run-protocol --resume {directory}"
        )
    if directory.exists() and any(directory.iterdir()):
        raise InvalidInput(f"{directory} exists and is not empty; choose another --session directory")
    proto_dir = directory / "protocol"
    try:
        proto_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise InvalidInput(
            f"--session {directory}: cannot create the session directory ({exc.strerror})"
        ) from None
    (directory / "units").mkdir(exist_ok=True)
    target = proto_dir / loaded.path.name
    target.write_text(loaded.text, encoding="utf-8")
    hashes: dict[str, str] = {}
    for rel in referenced_files(loaded):
        if not is_stored_with_session(rel):
            continue  # an absolute path into the shipped protocols (protocol/paths.py): read from there
        src = loaded.base_dir / rel
        dst = proto_dir / rel
        if not dst.resolve().is_relative_to(proto_dir.resolve()):
            raise InvalidInput(
                f"{loaded.path.name}: referenced file {rel} lies outside the protocol's folder"
            )
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(src, dst)
        hashes[rel] = sha256_of(dst)
    info = SessionInfo(
        protocol_name=loaded.protocol.name,
        protocol_sha256=loaded.sha256,
        protocol_file=str(target.relative_to(directory)),
        original_path=str(loaded.path),
        mode=mode,
        seed=seed,
        created_utc=datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
        only=only,
        software_version=__version__,
        realtime=realtime,
        files_sha256=hashes,
        rig_sha256=loaded.rig_source.sha256,
    )
    write_session_info(directory, info)
    return info


def write_session_info(directory: Path, info: SessionInfo) -> None:
    tmp = directory / (SESSION_FILE + ".partial")
    tmp.write_text(info.to_json(), encoding="utf-8")
    fsync_path(tmp)
    os.replace(tmp, directory / SESSION_FILE)
    fsync_path(directory)


def read_session_info(directory: Path) -> SessionInfo:
    from .info_check import parse_session_file

    path = directory / SESSION_FILE
    if not directory.is_dir():
        raise InvalidInput(f"{directory}: no such session directory")
    if not path.is_file():
        raise InvalidInput(
            f"{directory}: not a session directory (no {SESSION_FILE}); give the folder run-protocol created"
        )
    d = parse_session_file(path)
    d["only"] = tuple(d["only"])
    return SessionInfo(**d)


def changed_files(directory: Path, info: SessionInfo) -> list[str]:
    """The referenced files (copies in <session>/protocol/) whose sha256 differs from the one recorded at
    the session's creation, each as "path (changed)" or "path (missing)"."""
    out = []
    for rel, digest in sorted(info.files_sha256.items()):
        path = directory / "protocol" / rel
        if not path.is_file():
            out.append(f"{rel} ({'not a regular file' if os.path.lexists(path) else 'missing'})")
        elif sha256_of(path) != digest:
            out.append(f"{rel} (changed)")
    return out


def created_session_protocol(directory: Path, info: SessionInfo, loaded: LoadedProtocol) -> LoadedProtocol:
    """The protocol of a session `create_session` has just made from `loaded`, as `load_session_protocol`
    would read it back: the same validated protocol, named by its copy in <session>/protocol/ (that copy
    and the copies of its referenced files are byte for byte what `loaded` was read and checked from, so
    reading and checking them again would give the same result; a resume does read them again)."""
    path = directory / info.protocol_file
    return dataclasses.replace(loaded, path=path, shown=str(path))


def load_session_protocol(
    directory: Path, info: SessionInfo, *, force: bool
) -> tuple[LoadedProtocol, Plan, bool]:
    """Re-expand the protocol stored in the session; refuse a changed one, or a changed referenced file
    (calibration table, trajectory, reference data), unless `force`.

    Returns the protocol, its plan and whether its text or its rig file changed (accepted with --force)."""
    changes = changed_files(directory, info)
    if changes and not force:
        raise InvalidInput(
            f"{directory / 'protocol'}: {len(changes)} file(s) the protocol references changed since the "
            f"session began: {', '.join(changes)}. Completed trials were taken with the old files; restore "
            "them, or resume with --force to accept the change (recorded in the archive)."
        )
    path = directory / info.protocol_file
    loaded = load_protocol(path, display_name=str(path))
    changed = loaded.sha256 != info.protocol_sha256
    if changed and not force:
        raise InvalidInput(
            f"{path}: the protocol changed since the session began (sha256 {info.protocol_sha256[:12]}... "
            f"is now {loaded.sha256[:12]}...). Completed trials were taken under the old text; resume with "
            "--force to accept the change, or restore the file."
        )
    if info.rig_sha256 and loaded.rig_source.sha256 != info.rig_sha256:
        if not force:
            raise InvalidInput(
                f"{loaded.rig_source.shown}: the rig file changed since the session began (sha256 "
                f"{info.rig_sha256[:12]}... is now {loaded.rig_source.sha256[:12]}...). Completed trials were taken on "
                "the old rig description; restore it, or resume with --force to accept the change."
            )
        changed = True
    plan = expand(loaded, only=info.only or None)
    return loaded, plan, changed
