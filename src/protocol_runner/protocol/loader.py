"""Loading a protocol file: YAML -> validated `Protocol`, with errors that name file, line and field.

Every problem a user can make (a missing or empty file, a directory, binary garbage, YAML syntax, a wrong
type, an unknown key, an unknown level, a value out of range, a missing trajectory file) becomes an
`InvalidInput` whose message is one short paragraph of lines like

    knee_phase1.yaml:42: sets[1].configurations[2].friction: unknown level '5' (known: 0, 1, 2, 3, EMU)

Paths use 0-based indices, as in JSON paths.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence
from pathlib import Path
from typing import Any, get_origin

import yaml
from pydantic import BaseModel, ValidationError

from ..errors import InvalidInput
from ..resources import packaged_protocols_dir
from .loaded import LoadedProtocol as LoadedProtocol
from .loaded import Loc as Loc
from .loaded import clean_loc, line_for
from .schema import Protocol
from .validate import cross_check
from .yaml_limits import MAX_PROTOCOL_BYTES, check_size, check_yaml_limits

MAX_ERRORS_SHOWN = 8


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
    text: str, *, path: Path, display_name: str | None = None, check_files: bool = True
) -> LoadedProtocol:
    shown = display_name or str(path)
    if not text.strip() or all(ln.strip().startswith("#") or not ln.strip() for ln in text.splitlines()):
        raise InvalidInput(
            f"{shown}: the file is empty; a protocol needs at least `schema_version`, `name`, `rig`, ..."
        )
    check_size(len(text), shown)  # characters: a lower bound of the bytes
    check_yaml_limits(text, shown)  # before anything is composed or expanded
    try:
        node = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        raise InvalidInput(_yaml_error(shown, exc)) from None
    lines: dict[Loc, int] = {}
    duplicates: list[tuple[Loc, int]] = []
    if node is not None:
        _index_lines(node, (), lines, duplicates)
    if duplicates:
        loc, line = duplicates[0]
        raise InvalidInput(f"{shown}:{line}: {format_loc(loc)}: duplicate key (each key may appear once)")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:  # pragma: no cover - compose already succeeded
        raise InvalidInput(_yaml_error(shown, exc)) from None
    if not isinstance(data, dict):
        kind = type(data).__name__
        raise InvalidInput(
            f"{shown}:1: the top level must be a mapping of keys (schema_version, name, rig, ...), got {kind}"
        )
    try:
        protocol = Protocol.model_validate(data)
    except ValidationError as exc:
        problems = [(tuple(e["loc"]), _pydantic_message(e)) for e in exc.errors()]
        raise InvalidInput(format_problems(shown, lines, problems)) from None
    sha = hashlib.sha256(text.encode("utf-8")).hexdigest()
    loaded = LoadedProtocol(protocol=protocol, path=path, text=text, sha256=sha, lines=lines, shown=shown)

    problems = cross_check(loaded, check_files=check_files)
    if problems:
        raise InvalidInput(format_problems(shown, lines, problems))
    return loaded


def format_loc(loc: Sequence[str | int]) -> str:
    out = ""
    for part in loc:
        if isinstance(part, int):
            out += f"[{part}]"
        else:
            out += ("." if out else "") + str(part)
    return out or "(top level)"


def format_problems(shown: str, lines: dict[Loc, int], problems: Sequence[tuple[Loc, str]]) -> str:
    rows = []
    for loc, message in problems[:MAX_ERRORS_SHOWN]:
        line = line_for(lines, loc)
        where = f"{shown}:{line}" if line else shown
        rows.append(f"{where}: {format_loc(clean_loc(loc))}: {message}")
    if len(problems) > MAX_ERRORS_SHOWN:
        rows.append(f"(and {len(problems) - MAX_ERRORS_SHOWN} more problems)")
    return "\n".join(rows)


# ------------------------------------------------------------------------------------------ helpers


def _yaml_error(shown: str, exc: yaml.YAMLError) -> str:
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    context = getattr(exc, "context", None)
    line = f"{mark.line + 1}" if mark is not None else "?"
    detail = f"{context}, {problem}" if context else problem
    return f"{shown}:{line}: YAML syntax error: {detail}"


def _index_lines(node: yaml.Node, loc: Loc, lines: dict[Loc, int], dups: list[tuple[Loc, int]]) -> None:
    lines[loc] = node.start_mark.line + 1
    if isinstance(node, yaml.MappingNode):
        seen: set[str] = set()
        for key_node, value_node in node.value:
            key = str(key_node.value)
            child = (*loc, key)
            if key in seen:
                dups.append((child, key_node.start_mark.line + 1))
            seen.add(key)
            _index_lines(value_node, child, lines, dups)
            lines[child] = key_node.start_mark.line + 1
    elif isinstance(node, yaml.SequenceNode):
        for i, item in enumerate(node.value):
            _index_lines(item, (*loc, i), lines, dups)


def _pydantic_message(err: Any) -> str:
    kind = err.get("type", "")
    value = err.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(tuple(err["loc"][:-1]))
        hint = f" (allowed: {', '.join(allowed)})" if allowed else ""
        return f"unknown key{hint}"
    if kind == "missing":
        return "required field is missing"
    msg = str(err.get("msg", "invalid value"))
    msg = msg[0].lower() + msg[1:] if msg else msg
    if kind.startswith("value_error"):
        msg = msg.removeprefix("value error, ")
    if value is not None and not isinstance(value, (dict, list)):
        return f"{msg} (got {value!r})"
    return msg


def _allowed_keys(loc: Loc) -> list[str]:
    """The field names of the model at `loc` (for "unknown key" hints)."""
    model: Any = Protocol
    skip_user_key = False
    for part in clean_loc(loc):
        if isinstance(part, int):
            continue
        if skip_user_key:  # a key chosen by the user in a dict of models (level names, trajectory names)
            skip_user_key = False
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return []
        info = model.model_fields.get(str(part))
        if info is None:
            return []
        skip_user_key = get_origin(info.annotation) is dict
        model = _model_in(info.annotation)
    if isinstance(model, type) and issubclass(model, BaseModel):
        return list(model.model_fields)
    return []


def _model_in(annotation: Any) -> Any:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    return None
