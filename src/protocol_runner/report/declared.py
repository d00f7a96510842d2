"""Entries a protocol declares for the report, read back from the protocol text archived with the session.

Sections such as `expectations:` and `report.repeatability:` are parsed again from `/protocol/text`. A text
that is not YAML, or an entry that does not validate, gives a message instead of an error: the report still
renders and says what it could not read. `report.citations` names, per report part, where a reproduced
source shows the same thing ("thesis Figures 41-46"); nothing is cited unless the protocol says so.
"""

from __future__ import annotations

import functools
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from protocol_runner.protocol.schema import CitationsSpec

Spec = TypeVar("Spec", bound=BaseModel)


@functools.lru_cache(maxsize=4)
def protocol_document(protocol_text: str) -> Any:
    """The archived protocol text parsed as YAML, once per text, as the protocol loader reads a file
    (protocol/yaml_doc.py); None for an empty text. Read-only: every caller shares the one document.
    Raises `yaml.YAMLError`, also for a text over the loader's limits (size, nesting, aliases, numbers'
    length: an archive can be anyone's file) or one it cannot construct."""
    from protocol_runner.errors import InvalidInput
    from protocol_runner.protocol.yaml_doc import FAST_LOADER, SafeLoader
    from protocol_runner.protocol.yaml_limits import check_size, check_yaml_limits

    if not protocol_text.strip():
        return None
    try:
        check_size(len(protocol_text), "the archived protocol")
        check_yaml_limits(protocol_text, "the archived protocol", loader=SafeLoader)
    except InvalidInput as exc:
        raise yaml.YAMLError(exc.message) from None
    for loader in (FAST_LOADER or SafeLoader, SafeLoader):  # the pure-Python loader's message on an error
        try:
            return yaml.load(protocol_text, Loader=loader)
        except yaml.YAMLError:
            if loader is SafeLoader:
                raise
        except (ValueError, RecursionError) as exc:
            raise yaml.YAMLError(f"{type(exc).__name__}: {exc}") from None
    return None


def declared_entries(
    protocol_text: str, path: tuple[str, ...], model: type[Spec]
) -> tuple[tuple[Spec, ...], tuple[str, ...]]:
    """The list at `path` (keys from the top, e.g. ("report", "repeatability")) of an archived protocol
    text, each entry validated as `model`, and a message per entry (or per section) that is not valid."""
    where_list = ".".join(path)
    try:
        node = protocol_document(protocol_text)
    except yaml.YAMLError as exc:
        return (), (f"the archived protocol is not readable YAML ({exc.__class__.__name__})",)
    for key in path:
        node = node.get(key) if isinstance(node, dict) else None
    if node is None:
        return (), ()
    if not isinstance(node, list):
        return (), (f"{where_list}: must be a list",)
    specs: list[Spec] = []
    problems: list[str] = []
    for i, entry in enumerate(node):
        try:
            specs.append(model.model_validate(entry))
        except ValidationError as exc:
            first = exc.errors()[0]
            where = ".".join(str(p) for p in first["loc"]) or "entry"
            problems.append(f"{where_list}[{i}].{where}: {first['msg']}")
    return tuple(specs), tuple(problems)


def _declared_node(protocol_text: str, path: tuple[str, ...]) -> Any:
    """The value at `path` (keys from the top) of an archived protocol text; None when it has none or the
    text is not readable YAML."""
    try:
        node = protocol_document(protocol_text)
    except yaml.YAMLError:
        return None
    for key in path:
        node = node.get(key) if isinstance(node, dict) else None
    return node


def declared_text(protocol_text: str, key: str) -> str:
    """A top-level text of the archived protocol (`title`, `description`); "" when it has none."""
    value = _declared_node(protocol_text, (key,))
    return value.strip() if isinstance(value, str) else ""


def declared_count(protocol_text: str, path: tuple[str, ...]) -> int:
    """How many entries the list at `path` of an archived protocol text has (0 when there is none)."""
    node = _declared_node(protocol_text, path)
    return len(node) if isinstance(node, list) else 0


def declared_citations(protocol_text: str) -> dict[str, str]:
    """Every report part a protocol can cite (`protocol.schema.CitationsSpec`) mapped to its citation text
    ("" when none is declared, or the text is unreadable)."""
    declared = _declared_node(protocol_text, ("report", "citations"))
    declared = declared if isinstance(declared, dict) else {}
    return {
        part: text.strip() if isinstance(text := declared.get(part), str) else ""
        for part in CitationsSpec.model_fields
    }
