"""The session directory: a self-contained record of one campaign run.

    <session>/session.json        mode, seed, protocol name and sha256 (and each referenced file's), creation
                                  time, --only; checked field by field when read (`parse_session_file`)
    <session>/protocol/           the protocol file exactly as run, plus the files it references
    <session>/journal.jsonl       completed units and events (session/journal.py)
    <session>/units/*.h5          one atomic HDF5 file per finished step (archive/units.py)
    <session>/session.log         the run's log
    <session>/archive.h5          the consolidated archive (at the end, and at every stop)
    <session>/report.html         the report

Resume re-expands the protocol stored here, so it works even if the original file moved or changed. A
damaged or hand-edited session.json gets one clear error naming the field (exit 2), never a session run
with a value no run could have written.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import os
import re
import shutil
from dataclasses import MISSING, asdict, dataclass, field, fields
from datetime import UTC, datetime
from pathlib import Path, PurePosixPath
from typing import Any

from .. import __version__
from ..archive.diskfull import DiskFull, is_disk_full
from ..archive.units import fsync_path, sha256_of
from ..errors import InvalidInput
from ..protocol.loaded import LoadedProtocol
from ..protocol.loader import load_protocol
from ..protocol.paths import is_stored_with_session
from ..protocol.plan import expand
from ..protocol.plan_steps import Plan
from ..protocol.rig_file import is_rig_path
from ..protocol.trajectory_specs import trajectory_files

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


def default_session_dir(protocol_name: str) -> Path:
    return Path.cwd() / "sessions" / f"{protocol_name}-{datetime.now(UTC).strftime('%Y%m%dT%H%M%SZ')}"


def referenced_files(loaded: LoadedProtocol) -> list[str]:
    p = loaded.protocol
    files = list(dict.fromkeys(f for spec in p.trajectories.values() for f in trajectory_files(spec)))
    cal = p.rig.calibration
    files += [f for f in (cal.command_table, cal.angle_table, cal.torque_table) if f]
    if p.report.reference_dataset:
        files.append(p.report.reference_dataset)
    if is_rig_path(p.rig_name):  # a lab's own rig file beside the protocol: the session keeps its copy
        files.append(p.rig_name)
    return files


def create_session(
    directory: Path, loaded: LoadedProtocol, *, mode: str, seed: int, only: tuple[int, ...], realtime: bool
) -> SessionInfo:
    """Create the session directory with its protocol copies and session.json. If it fails writing (a full
    disk, no permission), what it wrote is removed, so that no half-made session is left behind, and one
    clear error is raised."""
    existed = directory.exists()
    try:
        was_empty = not existed or (directory.is_dir() and not any(directory.iterdir()))
    except OSError:
        was_empty = False
    try:
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
    except OSError as exc:
        if was_empty:  # only what this call wrote is removed
            with contextlib.suppress(OSError):
                if not existed:
                    shutil.rmtree(directory)
                else:
                    for child in directory.iterdir():
                        if child.is_dir() and not child.is_symlink():
                            shutil.rmtree(child)
                        else:
                            child.unlink()
        if is_disk_full(exc):
            raise DiskFull(
                f"disk full while creating the session {directory}: nothing was recorded. "
                "Free some space, then run the same command again."
            ) from None
        what = f"{exc.strerror}: {exc.filename}" if exc.strerror and exc.filename else (exc.strerror or exc)
        raise InvalidInput(f"--session {directory}: cannot create the session ({what})") from None


def write_session_info(directory: Path, info: SessionInfo) -> None:
    tmp = directory / (SESSION_FILE + ".partial")
    tmp.write_text(info.to_json(), encoding="utf-8")
    fsync_path(tmp)
    os.replace(tmp, directory / SESSION_FILE)
    fsync_path(directory)


def read_session_info(directory: Path) -> SessionInfo:
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
    """The protocol of a session `create_session` has just made from `loaded`, named by its copy in
    <session>/protocol/ (byte for byte what `loaded` was read and checked from, so not read again)."""
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


MODES = ("dry-run", "hardware")
MAX_SEED = 2**63 - 1
MAX_BYTES = 1 << 20  # a session file is a few hundred bytes
_SHA256 = re.compile(r"[0-9a-f]{64}")

REQUIRED = tuple(f.name for f in fields(SessionInfo) if f.default is MISSING and f.default_factory is MISSING)
OPTIONAL = tuple(f.name for f in fields(SessionInfo) if f.name not in REQUIRED)


def _inside(rel: object) -> bool:
    """A relative path that stays inside the directory it is relative to."""
    if not isinstance(rel, str) or not rel or "\\" in rel or "\x00" in rel:
        return False
    p = PurePosixPath(rel)
    return not p.is_absolute() and ".." not in p.parts


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def parse_session_file(path: Any) -> dict[str, Any]:
    """The fields of `path` (a session.json), checked; InvalidInput naming the first problem."""
    try:
        raw = path.read_bytes()[: MAX_BYTES + 1]
    except OSError as exc:
        raise InvalidInput(f"{path}: cannot read the session file ({exc.strerror})") from None
    if len(raw) > MAX_BYTES:
        raise InvalidInput(f"{path}: damaged session file (over {MAX_BYTES} bytes)")
    try:
        d = json.loads(raw.decode("utf-8"))
    except UnicodeDecodeError:
        raise InvalidInput(f"{path}: damaged session file (not UTF-8 text)") from None
    except json.JSONDecodeError as exc:
        raise InvalidInput(
            f"{path} line {exc.lineno}: damaged session file, not valid JSON ({exc.msg})"
        ) from None
    except RecursionError:
        raise InvalidInput(f"{path}: damaged session file (nested too deeply)") from None
    except ValueError:  # e.g. an integer of thousands of digits (Python's int conversion limit)
        raise InvalidInput(f"{path}: damaged session file (a number too long to read)") from None
    if not isinstance(d, dict):
        raise InvalidInput(f"{path}: damaged session file (expected a JSON object of fields)")

    def bad(field: str, why: str) -> InvalidInput:
        return InvalidInput(f"{path}: field {field!r} {why}")

    missing = [k for k in REQUIRED if k not in d]
    if missing:
        raise bad(missing[0], "is missing (damaged session file)")
    unknown = sorted(k for k in d if k not in REQUIRED + OPTIONAL)
    if unknown:
        raise bad(unknown[0], "is not a session field (damaged session file)")
    for key in ("protocol_name", "original_path", "created_utc", "software_version"):
        if not isinstance(d[key], str):
            raise bad(key, f"must be text, got {d[key]!r:.60}")
    if not isinstance(d["protocol_sha256"], str) or not _SHA256.fullmatch(d["protocol_sha256"]):
        raise bad("protocol_sha256", "must be 64 lower-case hex digits")
    if not _inside(d["protocol_file"]):
        raise bad(
            "protocol_file", f"must be a path inside the session directory, got {d['protocol_file']!r:.80}"
        )
    if d["mode"] not in MODES:
        raise bad("mode", f"must be one of {', '.join(MODES)}, got {d['mode']!r:.40}")
    if not _is_int(d["seed"]) or not 0 <= d["seed"] <= MAX_SEED:
        raise bad("seed", f"must be an integer from 0 to 2**63 - 1, got {d['seed']!r:.40}")
    only = d["only"]
    if not isinstance(only, list) or not all(_is_int(k) and k >= 0 for k in only):
        raise bad("only", f"must be a list of configuration keys (integers >= 0), got {only!r:.60}")
    if len(set(only)) != len(only):
        raise bad("only", "lists a configuration key twice")
    realtime = d.get("realtime", False)
    if not isinstance(realtime, bool):
        raise bad("realtime", f"must be true or false, got {realtime!r:.40}")
    if realtime and d["mode"] != "dry-run":
        raise bad("realtime", "can be true only in a dry-run session")
    files = d.get("files_sha256", {})
    if not isinstance(files, dict):
        raise bad("files_sha256", "must be an object of file path -> sha256")
    for rel, digest in files.items():
        if not _inside(rel):
            raise bad("files_sha256", f"names {rel!r:.80}, which is not a path inside the session directory")
        if not isinstance(digest, str) or not _SHA256.fullmatch(digest):
            raise bad("files_sha256", f"gives {rel!r:.80} a sha256 that is not 64 lower-case hex digits")
    rig = d.get("rig_sha256", "")
    if not isinstance(rig, str) or (rig and not _SHA256.fullmatch(rig)):
        raise bad("rig_sha256", f"must be empty or 64 lower-case hex digits, got {rig!r:.80}")
    return d
