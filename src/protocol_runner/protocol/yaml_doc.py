"""A YAML document with the line of every key, and problems formatted as `file:line: field: message`.

Shared by the protocol loader and the rig-file loader: both name the file, the line and the field of every
mistake (paths use 0-based list indices, as in JSON paths).
"""

from __future__ import annotations

import re
from collections.abc import Iterator, Sequence
from typing import Any, TypeVar, get_args, get_origin

import yaml
from pydantic import BaseModel, ValidationError

from ..errors import InvalidInput
from .loaded import Loc, line_for
from .yaml_limits import check_size, check_yaml_limits

MAX_ERRORS_SHOWN = 8
MISSING_FIELD = "required field is missing"


# YAML 1.1 (PyYAML) reads a number whose exponent has no decimal point or no sign (`2e1`, `2.5e1`) as text, which
# then fails as "not a number" in some fields and passes in others; YAML 1.2 reads it as the number it is.
_FLOAT_1_2 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class SafeLoader(yaml.SafeLoader):
    """`yaml.SafeLoader`, with numbers like `2e1` read as numbers (YAML 1.2)."""


FAST_LOADER: Any = type("FastLoader", (yaml.CSafeLoader,), {}) if hasattr(yaml, "CSafeLoader") else None
"""libyaml's safe loader when PyYAML was built with it (10-20x faster than the pure-Python one), with the
same YAML 1.2 numbers. It reads a document exactly as `SafeLoader` does; a document it refuses is read
again by the pure-Python loader, whose messages (and their line numbers) are the ones shown."""

for _loader in (SafeLoader, FAST_LOADER):
    if _loader is not None:
        _loader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_1_2, list("-+0123456789"))


def parse_yaml(text: str, shown: str) -> tuple[Any, dict[Loc, int]]:
    """The document's data and the line of every key and list item; InvalidInput on bad YAML or a key
    given twice."""
    check_size(len(text), shown)  # characters: a lower bound of the bytes
    node, data = None, None
    if FAST_LOADER is not None:
        try:
            check_yaml_limits(text, shown, loader=FAST_LOADER)  # before anything is composed or expanded
            node, data = _compose_and_construct(text, FAST_LOADER)
        except yaml.YAMLError:
            node = None  # read again below, for the pure-Python loader's message
    if node is None:
        check_yaml_limits(text, shown, loader=SafeLoader)
        try:
            node, data = _compose_and_construct(text, SafeLoader)
        except yaml.YAMLError as exc:
            raise InvalidInput(yaml_error(shown, exc, text)) from None
    lines: dict[Loc, int] = {}
    duplicates: list[tuple[Loc, int]] = []
    if node is not None:
        _index_lines(node, (), lines, duplicates)
    if duplicates:
        loc, line = duplicates[0]
        raise InvalidInput(f"{shown}:{line}: {format_loc(loc)}: duplicate key (each key may appear once)")
    for where, value in _scalars(data):  # the first key or text holding a control character
        code = next((ord(c) for c in value if _is_control(c)), None) if isinstance(value, str) else None
        if code is not None:
            raise InvalidInput(
                f"{shown}:{line_for(lines, where) or '?'}: {_escaped(format_loc(where))}: control character "
                f"U+{code:04X} in a text (terminal escape sequences and the like are refused: a label is "
                "printed on the operator's terminal)"
            )
    return data, lines


def _scalars(value: object, loc: Loc = ()) -> Iterator[tuple[Loc, object]]:
    """Every text key and every scalar of a document, with its place, in document order."""
    if isinstance(value, dict):
        for key, item in value.items():
            here = (*loc, str(key))
            if isinstance(key, str):
                yield here, key
            yield from _scalars(item, here)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            yield from _scalars(item, (*loc, i))
    else:
        yield loc, value


MAX_MAGNITUDE = 1e9
"""The largest magnitude a number in a protocol or rig file may have. No quantity of a campaign comes near
it in the units its field names (rates are at most tens of kHz, times hours, keys below a million), and a
bound keeps every later computation (a squared speed, a sample count) finite."""


def _huge_numbers(document: object) -> list[tuple[Loc, str]]:
    """The first number beyond `MAX_MAGNITUDE` in the document, as a problem at its place (checked after
    the schema, whose own bound on a field, where it has one, is the clearer message)."""
    for loc, value in _scalars(document):
        if isinstance(value, int | float) and not isinstance(value, bool) and abs(value) > MAX_MAGNITUDE:
            text = f"{value:.6g}" if isinstance(value, float) else str(value)
            shown = text if len(text) <= 15 else f"a {len(text)}-digit number"
            return [
                (
                    loc,
                    f"{shown} is beyond the {MAX_MAGNITUDE:.0e} any number of a campaign may be (check its "
                    "unit and exponent)",
                )
            ]
    return []


Model = TypeVar("Model", bound=BaseModel)


def validated(model: type[Model], data: object, shown: str, lines: dict[Loc, int]) -> Model:
    """`data` validated as `model`, then refused where it gives a boolean for a number or a number beyond
    `MAX_MAGNITUDE`; InvalidInput naming `shown`, the line and the field."""
    try:
        out = model.model_validate(data)
    except ValidationError as exc:
        raise InvalidInput(format_problems(shown, lines, validation_problems(exc, model))) from None
    problems = boolean_numbers(out, data) or _huge_numbers(data)
    if problems:
        raise InvalidInput(format_problems(shown, lines, problems))
    return out


def _escaped(text: str) -> str:
    """`text` with its control characters written as escapes (a message must not carry them either)."""
    return "".join(f"\\x{ord(c):02x}" if _is_control(c) else c for c in text)


def _is_control(character: str) -> bool:
    code = ord(character)
    return (code < 0x20 and character not in "\t\n") or 0x7F <= code <= 0x9F


def _compose_and_construct(text: str, loader_class: Any) -> tuple[yaml.Node | None, Any]:
    """The document's node tree and its data (constructed from that tree: the text is parsed once)."""
    loader = loader_class(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    finally:
        loader.dispose()
    return node, data


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
        rows.append(f"{where}: {format_loc(loc)}: {message}")
    if len(problems) > MAX_ERRORS_SHOWN:
        rows.append(f"(and {len(problems) - MAX_ERRORS_SHOWN} more problems)")
    return "\n".join(rows)


def validation_problems(exc: ValidationError, root: type[BaseModel]) -> list[tuple[Loc, str]]:
    """(location, message) for each pydantic error, with "allowed keys" hints from the `root` model.
    The alternatives of a union at one field are one message ("a valid list or 'all' (got 'al')")."""
    merged: dict[Loc, list[str]] = {}
    for e in exc.errors():
        merged.setdefault(_file_loc(tuple(e["loc"])), []).append(_pydantic_message(e, root))
    return _unknown_before_missing([(loc, _one_message(messages)) for loc, messages in merged.items()])


def _unknown_before_missing(problems: list[tuple[Loc, str]]) -> list[tuple[Loc, str]]:
    """A misspelt key makes two problems in one mapping, the field missing and the key unknown; pydantic
    lists the missing field first. The unknown keys of a mapping are moved before its first missing field:
    the typo is the cause, and it is read first. Everything else keeps its order."""
    out: list[tuple[Loc, str]] = []
    moved: set[int] = set()
    for i, (loc, message) in enumerate(problems):
        if i in moved:
            continue
        if message == MISSING_FIELD:
            for j in range(i + 1, len(problems)):
                other, text = problems[j]
                if j not in moved and other[:-1] == loc[:-1] and text.startswith("unknown key"):
                    out.append(problems[j])
                    moved.add(j)
        out.append((loc, message))
    return out


def _file_loc(loc: Loc) -> Loc:
    """`loc` without what pydantic adds to an error path that is no key of the file: the member of a plain
    union (`factors.damper.list[str]`, `...float`), the tags of the schema's own discriminated forms
    (`calibration_step.<one step>.hold_s`) and a trajectory's kind (`trajectories.sine.sinusoid.x`)."""
    from .trajectory_specs import kind_names

    kinds, members = kind_names(), {"str", "int", "float", "bool", "none", "list"}
    return tuple(
        p
        for i, p in enumerate(loc)
        if not (
            isinstance(p, str)
            and ("[" in p or p in members or p.startswith("literal") or p[:1] + p[-1:] == "<>")
        )
        and not (i >= 2 and loc[i - 2] in ("trajectories", "joints") and p in kinds)
    )


def _one_message(messages: list[str]) -> str:
    prefix = "input should be "
    if len(messages) < 2 or not all(m.startswith(prefix) for m in messages):
        return "; ".join(dict.fromkeys(messages))
    got = [m[m.rindex(" (got ") :] if m.endswith(")") and " (got " in m else "" for m in messages]
    bodies = [m[len(prefix) : len(m) - len(g)] for m, g in zip(messages, got, strict=True)]
    return prefix + " or ".join(dict.fromkeys(bodies)) + (got[0] if len(set(got)) == 1 else "")


def yaml_error(shown: str, exc: yaml.YAMLError, text: str = "") -> str:
    mark = getattr(exc, "problem_mark", None)
    problem = getattr(exc, "problem", None) or str(exc)
    context = getattr(exc, "context", None)
    line = f"{mark.line + 1}" if mark is not None else "?"
    if isinstance(exc, yaml.reader.ReaderError) and text:
        # a character YAML does not allow: the reader gives its position in the text, not a line
        line = f"{text.count(chr(10), 0, exc.position) + 1}"
        code = exc.character if isinstance(exc.character, int) else ord(exc.character)
        problem = f"character #x{code:04x} is not allowed in YAML ({exc.reason})"
    detail = f"{context}, {problem}" if context else problem
    hint = " (indent with spaces: YAML does not allow tabs)" if "'\\t'" in detail else ""
    begun = getattr(exc, "context_mark", None)
    if not hint and begun is not None and mark is not None and "expected <block end>" in detail:
        # the line found is where the parser gave up; the mistake may be the line that began the mapping
        first, found = begun.line + 1, mark.line + 1
        lines = f"lines {first} and {found}" if first != found else f"line {found} and the one above"
        hint = f" (the keys of one mapping must line up: compare the indentation of {lines})"
    elif not hint and mark is not None and "mapping values are not allowed here" in detail:
        hint = (
            f" (a key indented deeper than the one above it, or a ': ' inside an unquoted value: compare the "
            f"indentation of line {mark.line + 1} with the line above, or quote the value)"
        )
    return f"{shown}:{line}: YAML syntax error: {detail}{hint}"


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


def _pydantic_message(err: Any, root: type[BaseModel]) -> str:
    kind = err.get("type", "")
    value = err.get("input")
    if kind == "extra_forbidden":
        allowed = _allowed_keys(root, tuple(err["loc"][:-1]))
        hint = f" (allowed: {', '.join(allowed)})" if allowed else ""
        return f"unknown key{hint}"
    if kind == "missing":
        return MISSING_FIELD
    if kind == "model_type":  # pydantic names its class: say what the file should hold there
        keys = _allowed_keys(root, _file_loc(tuple(err["loc"])))
        shown = f" with keys {', '.join(keys)}" if keys else ""
        return f"input should be a mapping{shown} (got {value!r})"
    if kind == "union_tag_invalid":
        ctx = err.get("ctx") or {}
        return f"unknown kind {ctx.get('tag')!r} (known: {ctx.get('expected_tags', '')})"
    msg = str(err.get("msg", "invalid value"))
    msg = msg[0].lower() + msg[1:] if msg else msg
    if kind.startswith("value_error"):
        msg = msg.removeprefix("value error, ")
    if value is not None and not isinstance(value, (dict, list)) and not _names_value(msg, value):
        return f"{msg} (got {value!r})"
    return msg


def _names_value(msg: str, value: object) -> bool:
    """Whether a validator's own message already says what it got (`..., got -30`)."""
    shown = {repr(value)} | (
        {f"{value:g}"} if isinstance(value, int | float) and not isinstance(value, bool) else set()
    )
    return any(f"got {text}" in msg for text in shown)


def _allowed_keys(root: type[BaseModel], loc: Loc) -> list[str]:
    """The keys of the model at `loc` (for "unknown key" hints)."""
    model: Any = root
    skip_user_key = False
    for part in _file_loc(loc):
        if isinstance(part, int):
            continue
        if skip_user_key:  # a key chosen by the user in a dict of models (level names, trajectory names)
            skip_user_key = False
            continue
        if not (isinstance(model, type) and issubclass(model, BaseModel)):
            return []
        info = next((f for name, f in model.model_fields.items() if (f.alias or name) == part), None)
        if info is None:
            return []
        skip_user_key = get_origin(info.annotation) is dict
        model = _model_in(info.annotation)
    if isinstance(model, type) and issubclass(model, BaseModel):
        return [info.alias or name for name, info in model.model_fields.items()]
    return []


def _model_in(annotation: Any) -> Any:
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    for arg in getattr(annotation, "__args__", ()) or ():
        found = _model_in(arg)
        if found is not None:
            return found
    return None


# Booleans where the schema wants numbers: YAML reads `yes`, `no`, `on`, `off`, `true` and `false` as booleans,
# and pydantic takes one for 1 or 0 in a number field (`periods: yes` became 1 period). After a file validates,
# `boolean_numbers` walks the validated model beside the file's data and names every number field (alone, or
# an item of its list or mapping) the file gave a boolean. Fields that may hold a boolean are left alone.

BOOLEAN_MESSAGE = "expected a number, got {value!r} (YAML reads yes, no, on, off, true and false as booleans)"


def boolean_numbers(model: BaseModel, data: object, loc: Loc = ()) -> list[tuple[Loc, str]]:
    """(location, message) of every number field of `model` (and of the models inside it) that `data`,
    the mapping it was validated from, gives as a boolean."""
    if not isinstance(data, dict):
        return []
    out: list[tuple[Loc, str]] = []
    for name, field in type(model).model_fields.items():
        key = field.alias or name
        if key not in data:
            continue
        raw, value, here = data[key], getattr(model, name), (*loc, key)
        if _numbers_not_booleans(field.annotation):
            out += [(where, BOOLEAN_MESSAGE.format(value=b)) for where, b in _booleans(raw, here)]
        else:
            out += _inside(value, raw, here)
    return out


def _inside(value: object, raw: object, loc: Loc) -> list[tuple[Loc, str]]:
    """The models held by a field's value (a model, or a list or mapping of them), each against its data."""
    if isinstance(value, BaseModel):
        return boolean_numbers(value, raw, loc)
    out: list[tuple[Loc, str]] = []
    if isinstance(value, list | tuple) and isinstance(raw, list) and len(raw) == len(value):
        for i, (v, r) in enumerate(zip(value, raw, strict=True)):
            out += _inside(v, r, (*loc, i))
    elif isinstance(value, dict) and isinstance(raw, dict):
        by_text = {str(k): k for k in raw}
        for k, v in value.items():
            if str(k) in by_text:
                out += _inside(v, raw[by_text[str(k)]], (*loc, str(k)))
    return out


def _booleans(raw: object, loc: Loc) -> list[tuple[Loc, bool]]:
    if isinstance(raw, bool):
        return [(loc, raw)]
    if isinstance(raw, list):
        return [((*loc, i), v) for i, v in enumerate(raw) if isinstance(v, bool)]
    if isinstance(raw, dict):
        return [((*loc, str(k)), v) for k, v in raw.items() if isinstance(v, bool)]
    return []


def _kinds(annotation: object) -> set[object]:
    """The plain types an annotation is made of (through unions, Annotated, containers; a Literal's
    booleans count as bool)."""
    out: set[object] = {annotation} if isinstance(annotation, type) or annotation is Any else set()
    if isinstance(annotation, bool):
        out.add(bool)
    for arg in get_args(annotation):
        out |= _kinds(arg)
    return out


def _numbers_not_booleans(annotation: object) -> bool:
    """Whether a field of this annotation holds plain numbers (no booleans, no models, nothing at all)."""
    kinds = _kinds(annotation)
    if kinds & {bool, Any, object} or any(isinstance(k, type) and issubclass(k, BaseModel) for k in kinds):
        return False
    return bool(kinds & {float, int})
