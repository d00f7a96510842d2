"""Every archive attribute name that a module of src/ reads or writes by hand is one archive/attrs.py
declares (and tests/archive/test_paths.py checks docs/archive.md against that module): a reader or a
writer that misspells a name, or uses one the layout does not know, fails here."""

from __future__ import annotations

import ast
from pathlib import Path

from protocol_runner.archive import attrs

SRC = Path(__file__).resolve().parents[2] / "src" / "protocol_runner"
READERS = {"attr_str", "attr_float", "attr_int", "attr_floats", "attr_bool", "attr_strs"}
DECLARED = {name for names in attrs.ATTRIBUTES.values() for name in names}


def _is_attrs(node: ast.expr) -> bool:
    """`<something>.attrs`, or a name bound to one (`a = grp.attrs`)."""
    return (isinstance(node, ast.Attribute) and node.attr == "attrs") or (
        isinstance(node, ast.Name) and node.id in {"attrs", "a"}
    )


def _text(node: ast.expr | None) -> str | None:
    return node.value if isinstance(node, ast.Constant) and isinstance(node.value, str) else None


def names_used(tree: ast.AST) -> list[tuple[int, str]]:
    """(line, name) of every attribute name spelled as a literal where an attribute is read or written."""
    out: list[tuple[int, str]] = []
    for node in ast.walk(tree):
        name = None
        if isinstance(node, ast.Call):
            func = node.func
            called = (
                func.id
                if isinstance(func, ast.Name)
                else func.attr
                if isinstance(func, ast.Attribute)
                else ""
            )
            if called in READERS and len(node.args) >= 2:
                name = _text(node.args[1])
            elif called == "get" and isinstance(func, ast.Attribute) and _is_attrs(func.value) and node.args:
                name = _text(node.args[0])
        elif isinstance(node, ast.Subscript) and _is_attrs(node.value):
            name = _text(node.slice)
        elif isinstance(node, ast.Compare) and isinstance(node.ops[0], ast.In | ast.NotIn):
            name = _text(node.left) if _is_attrs(node.comparators[0]) else None
        if name is not None:
            out.append((node.lineno, name))
    return out


def test_the_scan_finds_names_where_they_are_read_and_knows_an_undeclared_one() -> None:
    code = 'x = attr_str(g.attrs, "status")\ny = g.attrs["units"]\nz = "key" in cfg.attrs\nw = a.get("filter_cutof")\n'
    found = names_used(ast.parse(code))
    assert sorted(found) == [(1, "status"), (2, "units"), (3, "key"), (4, "filter_cutof")]
    assert [name for _, name in found if name not in DECLARED] == ["filter_cutof"]


def test_every_attribute_name_spelled_in_src_is_declared() -> None:
    unknown = [
        f"{path.relative_to(SRC)}:{line}: {name}"
        for path in sorted(SRC.rglob("*.py"))
        for line, name in names_used(ast.parse(path.read_text(encoding="utf-8")))
        if name not in DECLARED
    ]
    assert unknown == []
