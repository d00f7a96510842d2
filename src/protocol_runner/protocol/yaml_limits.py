"""Bounded work on a hostile protocol file: size, nesting depth and alias expansion are capped.

YAML anchors and aliases let a few hundred bytes stand for billions of nodes (the "billion laughs"
file), and deep nesting makes PyYAML's recursive composer raise RecursionError. Both are caught here by
one pass over the parser's event stream (iterative, memory bounded by the file size), before anything
is composed or expanded: every node counts as 1, an alias counts as the whole subtree it repeats, and
an alias's depth is where it stands plus the height of what it repeats. A protocol needs a few
thousand nodes at a depth of about 6 (protocols/knee_phase1.yaml: 1,200 nodes, depth 5).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Any

import yaml

from ..errors import InvalidInput

MAX_PROTOCOL_BYTES = 1_000_000
MAX_DEPTH = 40
MAX_NODES = 200_000
MAX_ALIASES = 10_000


@dataclass
class _Open:
    anchor: str | None
    nodes: int = 1
    height: int = 1


def check_size(n_bytes: int, shown: str) -> None:
    """Refuse a protocol file over `MAX_PROTOCOL_BYTES` (read at most one byte more than that)."""
    if n_bytes > MAX_PROTOCOL_BYTES:
        raise InvalidInput(
            f"{shown}: the file is larger than {MAX_PROTOCOL_BYTES // 1000} kB; "
            "a protocol file is a few tens of kB (is this the right file?)"
        )


MAX_NUMBER_CHARS = 400
_NUMBER = re.compile(r"[-+]?[0-9_.]+(?:[eE][-+]?[0-9_]+)?")  # a plain scalar YAML reads as a number


def check_yaml_limits(text: str, shown: str, loader: Any = yaml.SafeLoader) -> None:
    """Raise `InvalidInput` naming file and line if the YAML nests too deep, repeats too much through
    aliases, or its expanded tree has too many nodes. YAML syntax errors are left to the composer (with
    `yaml.CSafeLoader` as `loader`, raised here: the caller reads the text again with the pure-Python
    loader for its message)."""
    fast = not issubclass(loader, yaml.SafeLoader)
    stack: list[_Open] = []
    nodes: dict[str, int] = {}
    heights: dict[str, int] = {}
    open_anchors: set[str] = set()
    total = 0
    aliases = 0
    try:
        for event in yaml.parse(text, Loader=loader):
            line = event.start_mark.line + 1 if event.start_mark is not None else 0
            if isinstance(event, yaml.AliasEvent):
                aliases += 1
                anchor = str(event.anchor)
                if anchor in open_anchors:
                    raise InvalidInput(
                        f"{shown}:{line}: alias *{anchor} repeats a collection from inside itself "
                        "(a recursive structure); write the values out"
                    )
                if aliases > MAX_ALIASES:
                    raise InvalidInput(
                        f"{shown}:{line}: more than {MAX_ALIASES} YAML aliases (*name); write the values out"
                    )
                size, height = nodes.get(anchor, 1), heights.get(anchor, 1)
                total = _add(stack, size, height, total, shown, line)
            elif isinstance(event, yaml.ScalarEvent):
                total = _add(stack, 1, 1, total, shown, line)
                if not event.style and len(event.value) > MAX_NUMBER_CHARS and _NUMBER.fullmatch(event.value):
                    raise InvalidInput(
                        f"{shown}:{line}: a number written with {len(event.value)} characters; a number is at "
                        f"most {MAX_NUMBER_CHARS} (no measurement needs more digits)"
                    )
                if event.anchor is not None:
                    nodes[str(event.anchor)], heights[str(event.anchor)] = 1, 1
            elif isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                total = _count(total + 1, shown, line)
                name = None if event.anchor is None else str(event.anchor)
                stack.append(_Open(name))
                if name is not None:
                    open_anchors.add(name)
                if len(stack) > MAX_DEPTH:
                    raise InvalidInput(
                        f"{shown}:{line}: the YAML nests deeper than {MAX_DEPTH} levels; "
                        "a protocol needs about 6"
                    )
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                done = stack.pop()
                if done.anchor is not None:
                    open_anchors.discard(done.anchor)
                    nodes[done.anchor], heights[done.anchor] = done.nodes, done.height
                if stack:
                    stack[-1].nodes += done.nodes
                    stack[-1].height = max(stack[-1].height, done.height + 1)
    except yaml.YAMLError:
        if fast:
            raise
        return  # the composer reports the syntax error with its line


def _add(stack: list[_Open], size: int, height: int, total: int, shown: str, line: int) -> int:
    """Count a node (or an alias's repeated subtree) into every open collection."""
    if len(stack) + height > MAX_DEPTH:
        raise InvalidInput(
            f"{shown}:{line}: the YAML nests deeper than {MAX_DEPTH} levels (through aliases); "
            "a protocol needs about 6"
        )
    if stack:
        stack[-1].nodes += size
        stack[-1].height = max(stack[-1].height, height + 1)
    return _count(total + size, shown, line)


def _count(total: int, shown: str, line: int) -> int:
    if total > MAX_NODES:
        raise InvalidInput(
            f"{shown}:{line}: the YAML expands to more than {MAX_NODES:,} values (through aliases, "
            "*name); a protocol has a few thousand. Write the repeated values out or remove the aliases"
        )
    return total
