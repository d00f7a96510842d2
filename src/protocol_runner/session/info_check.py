"""Reading `session.json` field by field: a damaged or hand-edited file gets one clear error naming the
field (exit 2), never a traceback, and never a session run with a value no run could have written (a
negative seed, an unknown mode treated as hardware, a protocol path outside the session directory)."""

from __future__ import annotations

import json
import re
from pathlib import PurePosixPath
from typing import Any

from ..errors import InvalidInput

MODES = ("dry-run", "hardware")
MAX_SEED = 2**63 - 1
MAX_BYTES = 1 << 20  # a session file is a few hundred bytes
_SHA256 = re.compile(r"[0-9a-f]{64}")

REQUIRED = (
    "protocol_name",
    "protocol_sha256",
    "protocol_file",
    "original_path",
    "mode",
    "seed",
    "created_utc",
    "only",
    "software_version",
)
OPTIONAL = ("realtime", "files_sha256", "rig_sha256")


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
    check_session_fields(d, str(path))
    return d


def check_session_fields(d: dict[str, Any], where: str) -> None:
    def bad(field: str, why: str) -> InvalidInput:
        return InvalidInput(f"{where}: field {field!r} {why}")

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
