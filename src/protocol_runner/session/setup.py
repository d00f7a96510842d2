"""The session directory: a self-contained record of one campaign run.

    <session>/session.json        mode, seed, protocol name and sha256, creation time, --only
    <session>/protocol/           the protocol file exactly as run, plus the files it references
    <session>/journal.jsonl       completed units and events (session/journal.py)
    <session>/units/*.h5          one atomic HDF5 file per finished step (archive/units.py)
    <session>/session.log         the run's log
    <session>/archive.h5          the consolidated archive (at the end, and at every stop)
    <session>/report.html         the report

Resume re-expands the protocol stored here, so it works even if the original file moved or changed.
"""

from __future__ import annotations

import json
import os
import shutil
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from pathlib import Path

from .. import __version__
from ..archive.diskfull import creates_session_directory
from ..errors import InvalidInput
from ..protocol.loader import LoadedProtocol, load_protocol
from ..protocol.paths import is_stored_with_session
from ..protocol.plan import Plan, expand

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

    def to_json(self) -> str:
        d = asdict(self)
        d["only"] = list(self.only)
        return json.dumps(d, indent=2)


def default_session_dir(protocol_name: str, cwd: Path | None = None) -> Path:
    stamp = datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    return (cwd or Path.cwd()) / "sessions" / f"{protocol_name}-{stamp}"


def referenced_files(loaded: LoadedProtocol) -> list[str]:
    p = loaded.protocol
    files = [spec.file for spec in p.trajectories.human.values()]
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
    )
    write_session_info(directory, info)
    return info


def write_session_info(directory: Path, info: SessionInfo) -> None:
    tmp = directory / (SESSION_FILE + ".partial")
    tmp.write_text(info.to_json(), encoding="utf-8")
    with tmp.open("rb") as f:
        os.fsync(f.fileno())
    os.replace(tmp, directory / SESSION_FILE)
    fd = os.open(directory, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def read_session_info(directory: Path) -> SessionInfo:
    path = directory / SESSION_FILE
    if not directory.is_dir():
        raise InvalidInput(f"{directory}: no such session directory")
    if not path.is_file():
        raise InvalidInput(
            f"{directory}: not a session directory (no {SESSION_FILE}); give the folder run-protocol created"
        )
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
        d["only"] = tuple(d.get("only", ()))
        return SessionInfo(**d)
    except (json.JSONDecodeError, TypeError, KeyError) as exc:
        raise InvalidInput(f"{path}: unreadable session file ({exc})") from None


def load_session_protocol(
    directory: Path, info: SessionInfo, *, force: bool
) -> tuple[LoadedProtocol, Plan, bool]:
    """Re-expand the protocol stored in the session; refuse a changed one unless `force`.

    Returns the protocol, its plan and whether it changed (accepted with --force)."""
    path = directory / info.protocol_file
    loaded = load_protocol(path, display_name=str(path))
    changed = loaded.sha256 != info.protocol_sha256
    if changed and not force:
        raise InvalidInput(
            f"{path}: the protocol changed since the session began (sha256 {info.protocol_sha256[:12]}... "
            f"is now {loaded.sha256[:12]}...). Completed trials were taken under the old text; resume with "
            "--force to accept the change, or restore the file."
        )
    plan = expand(loaded, only=info.only or None)
    return loaded, plan, changed
