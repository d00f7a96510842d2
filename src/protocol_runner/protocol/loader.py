"""Loading a protocol file: YAML -> validated `Protocol`, with errors that name file, line and field.

Every problem a user can make (a missing or empty file, a directory, binary garbage, YAML syntax, a wrong
type, an unknown key, an unknown level, a value out of range, a missing trajectory file) becomes an
`InvalidInput` whose message is one short paragraph of lines like

    campaign.yaml:42: sets[1].configurations[2].brake: unknown level '5' (known: b0, b1, b2)

Paths use 0-based indices, as in JSON paths.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

from ..errors import InvalidInput
from ..resources import packaged_protocols_dir
from .generators import expand_generators
from .loaded import LoadedProtocol, line_for
from .rig_file import find_rig, load_rig, parse_rig_text, resolve_rigs
from .schema import Protocol
from .validate import cross_check
from .yaml_doc import format_problems, parse_yaml, validated
from .yaml_limits import MAX_PROTOCOL_BYTES, check_size


def find_protocol(name_or_path: str, cwd: Path | None = None) -> Path:
    """A path as given, or a bare file name looked up in ./protocols/ and then the packaged protocols."""
    cwd = cwd or Path.cwd()
    given = Path(name_or_path)
    candidates = [given if given.is_absolute() else cwd / given]
    if len(given.parts) == 1:
        names = [given.name] if given.suffix else [given.name, given.name + ".yaml", given.name + ".yml"]
        for n in names:
            candidates.append(cwd / "protocols" / n)
            candidates.append(packaged_protocols_dir() / n)
    for candidate in candidates:
        if candidate.exists():
            return candidate
    looked = ", ".join(str(c) for c in dict.fromkeys(candidates))
    raise InvalidInput(f"{name_or_path}: protocol file not found (looked in: {looked})")


def load_protocol(path: Path, *, display_name: str | None = None, check_files: bool = True) -> LoadedProtocol:
    """Read, parse and validate a protocol file. Raises `InvalidInput` with file:line: field: message."""
    shown = display_name or str(path)
    text = read_protocol_text(path, shown)
    return parse_protocol_text(text, path=path, display_name=shown, check_files=check_files)


def read_protocol_text(path: Path, shown: str) -> str:
    if not path.exists():
        raise InvalidInput(f"{shown}: protocol file not found")
    if path.is_dir():
        raise InvalidInput(f"{shown}: is a directory, expected a protocol file (.yaml)")
    if not path.is_file():  # a FIFO or a device: its read would wait forever, or never end
        raise InvalidInput(
            f"{shown}: not a regular file (a FIFO or a device), expected a protocol file (.yaml)"
        )
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_PROTOCOL_BYTES + 1)  # bounded even for a device or a huge file
    except OSError as exc:
        raise InvalidInput(f"{shown}: cannot read the protocol file ({exc.strerror})") from None
    check_size(len(raw), shown)
    if b"\x00" in raw:
        raise InvalidInput(f"{shown}: is a binary file, not a YAML protocol")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InvalidInput(
            f"{shown}:{line}: not valid UTF-8 text (byte {exc.start}); is this a protocol file?"
        ) from None
    return text


def parse_protocol_text(
    text: str,
    *,
    path: Path,
    display_name: str | None = None,
    check_files: bool = True,
    rig_text: str | None = None,
) -> LoadedProtocol:
    shown = display_name or str(path)
    if not text.strip() or all(ln.strip().startswith("#") or not ln.strip() for ln in text.splitlines()):
        raise InvalidInput(
            f"{shown}: the file is empty; a protocol needs at least `schema_version`, `name`, `rig`, ..."
        )
    data, lines = parse_yaml(text, shown)
    if not isinstance(data, dict):
        kind = type(data).__name__
        raise InvalidInput(
            f"{shown}:1: the top level must be a mapping of keys (schema_version, name, rig, ...), got {kind}"
        )
    if data.get("schema_version") == 1:
        raise InvalidInput(
            f"{shown}:{line_for(lines, ('schema_version',))}: schema_version: version 1 (fixed knee "
            "`levels:`) is no longer read; declare `factors:`, `device:` and named `trajectories:` as in "
            "schema_version 2 (docs/protocol.md; protocols/knee_phase1.yaml is the knee campaign in it)"
        )
    protocol = validated(Protocol, data, shown, lines)
    base_dir = path.parent
    if rig_text is not None:  # the rig file's text as archived with the run (`--reprocess`)
        loaded_rig = parse_rig_text(rig_text, base_dir / protocol.rig_name, f"{shown} (archived rig)")
    else:
        try:
            rig_path = find_rig(protocol.rig_name, base_dir)
        except InvalidInput as exc:
            raise InvalidInput(format_problems(shown, lines, [(("rig",), exc.message)])) from None
        # messages name a shipped rig by its file name in the package, a path as given
        shipped = protocol.rig_name == rig_path.stem and "/" not in protocol.rig_name
        loaded_rig = load_rig(rig_path, shown=f"rigs/{rig_path.name}" if shipped else protocol.rig_name)
    joints, overrides = list(protocol.driven_joints), protocol.rig_overrides
    rigs, problems = resolve_rigs(loaded_rig, joints, overrides, multi=protocol.multi_joint)
    if not rigs:
        raise InvalidInput(format_problems(shown, lines, problems))
    protocol, problems, origins = expand_generators(protocol.with_rigs(rigs))
    for generated, generator in origins.items():
        line = line_for(lines, generator)
        if line is not None:
            lines[generated] = line
    if problems:
        raise InvalidInput(format_problems(shown, lines, problems))
    sha = hashlib.sha256(text.encode("utf-8")).hexdigest()
    loaded = LoadedProtocol(protocol, path, text, sha, lines, shown, loaded_rig)

    problems = cross_check(loaded, check_files=check_files, generated=origins)
    if problems:
        raise InvalidInput(format_problems(shown, lines, problems))
    return loaded
