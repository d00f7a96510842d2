"""The package uses its dependencies through their public APIs only.

A private module or attribute of a dependency (a name with a leading underscore) changes without notice
in any release, and code that leans on one breaks silently or has to turn itself off. So does code that
re-builds a dependency's own pipeline from its low-level calls (HDF5 chunks written and read by hand).
This test reads every module of src/ (AST, no import) and fails naming the file and line of:

- an import of a private module of another package (`scipy.optimize._lsq`, `matplotlib._api`);
- an attribute with a single leading underscore that the package itself never defines (so it belongs to
  something else: `Text._get_layout`, `multiprocessing.forkserver._forkserver`, `atexit._run_exitfuncs`);
- the low-level chunk calls of h5py (`write_direct_chunk`, `read_direct_chunk`).
"""

from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SRC = REPO / "src" / "protocol_runner"
FORBIDDEN_ATTRIBUTES = {"write_direct_chunk", "read_direct_chunk"}
# documented public names that start with an underscore: namedtuple's methods (underscored so as not to
# clash with field names), the standard library's documented `_thread` module and `os._exit` (the one way
# to end a process from a thread other than its main one)
DOCUMENTED_PUBLIC = {"_asdict", "_replace", "_fields", "_make", "_field_defaults", "_thread", "_exit"}


def _modules() -> list[Path]:
    return sorted(SRC.rglob("*.py"))


def _trees() -> dict[Path, ast.Module]:
    return {path: ast.parse(path.read_text(encoding="utf-8"), str(path)) for path in _modules()}


def _is_private(name: str) -> bool:
    return name.startswith("_") and not name.startswith("__") and name not in DOCUMENTED_PUBLIC


def _own_private_names(trees: dict[Path, ast.Module]) -> set[str]:
    """Every underscore name the package defines: functions, classes, assignments, attributes it sets,
    parameters, module names, and the fields of its dataclasses and models."""
    names = {path.stem for path in _modules()}
    for tree in trees.values():
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                names.add(node.name)
            elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
                names.add(node.id)
            elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
                names.add(node.attr)
            elif isinstance(node, ast.arg):
                names.add(node.arg)
            elif isinstance(node, ast.alias):
                names.add(node.asname or node.name.split(".")[0])
    return {n for n in names if _is_private(n)}


def test_no_private_module_of_another_package_is_imported() -> None:
    found = []
    for path, tree in _trees().items():
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                modules = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules = [node.module]
            else:
                continue
            for module in modules:
                parts = module.split(".")
                if parts[0] != "protocol_runner" and any(_is_private(p) for p in parts):
                    found.append(f"{path.relative_to(REPO)}:{node.lineno}: import of {module}")
    assert not found, "\n".join(found)


def test_no_private_attribute_of_a_dependency_is_used() -> None:
    trees = _trees()
    own = _own_private_names(trees)
    found = []
    for path, tree in trees.items():
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute):
                if (_is_private(node.attr) and node.attr not in own) or node.attr in FORBIDDEN_ATTRIBUTES:
                    found.append(f"{path.relative_to(REPO)}:{node.lineno}: .{node.attr}")
            elif (
                isinstance(node, ast.ImportFrom)
                and node.level == 0
                and node.module
                and not node.module.startswith("protocol_runner")
            ):
                found += [
                    f"{path.relative_to(REPO)}:{node.lineno}: from {node.module} import {alias.name}"
                    for alias in node.names
                    if _is_private(alias.name)
                ]
    assert not found, "\n".join(found)


def test_the_check_would_see_a_private_attribute() -> None:
    """The walk above finds what it looks for: a foreign private attribute in a snippet is flagged."""
    tree = ast.parse("import atexit\natexit._run_exitfuncs()\nself._mine = 1\nself._mine\n")
    own = {n for n in ("_mine",)}
    flagged = [
        n.attr
        for n in ast.walk(tree)
        if isinstance(n, ast.Attribute) and _is_private(n.attr) and n.attr not in own
    ]
    assert flagged == ["_run_exitfuncs"]
