"""The import graph follows the data flow (docs/architecture.md): no upward import, no cycle.

Every import counts: module level, inside functions and under ``TYPE_CHECKING``. There is no
exception list; a new edge that breaks the order fails here with the module and line.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

# the source tree of this checkout (the installed copy may be elsewhere: a wheel in site-packages)
REPO = Path(__file__).resolve().parents[1]
PACKAGE_ROOT = REPO / "src" / "protocol_runner"

# Layer of each top-level package or module of protocol_runner. A module may import from its own
# top-level package and from any lower layer; never from the same layer (another name) or higher. The
# package's root (`__init__`) re-exports the Python interface (`api`), so it stands at the top; any module
# may read its `__version__`.
LAYERS: dict[str, int] = {
    "errors": 0,
    "resources": 0,
    "numba_cache": 0,
    "tables": 1,
    "models": 1,
    "hardware": 2,
    "analysis": 2,
    "protocol": 3,
    "archive": 4,
    "events": 4,
    "report": 5,
    "steps": 6,
    "session": 7,
    "monitor": 8,
    "preflight": 8,
    "power_plan": 8,
    "commands": 9,
    "cli": 10,
    "api": 10,
    "__main__": 11,
    "__init__": 11,
}


def _module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE_ROOT.parent).with_suffix("")
    name = ".".join(rel.parts)
    return name.removesuffix(".__init__")


def _imports(path: Path) -> list[tuple[str, int]]:
    """Every protocol_runner module named by an import in ``path``, with its line."""
    name = _module_name(path)
    package = name if path.name == "__init__.py" else name.rsplit(".", 1)[0]
    found: list[tuple[str, int]] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
                target = f"{base}.{node.module}" if node.module else base
            else:
                target = node.module or ""
            found.append((target, node.lineno))
            # "from . import x" / "from .pkg import mod" may name submodules
            for alias in node.names:
                candidate = f"{target}.{alias.name}"
                if _exists(candidate):
                    found.append((candidate, node.lineno))
    return [(t, line) for t, line in found if t.split(".")[0] == "protocol_runner"]


def _exists(module: str) -> bool:
    rel = Path(*module.split(".")[1:])
    return (PACKAGE_ROOT / rel).with_suffix(".py").is_file() or (PACKAGE_ROOT / rel / "__init__.py").is_file()


def _top(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _graph() -> dict[str, list[tuple[str, int]]]:
    return {_module_name(path): _imports(path) for path in sorted(PACKAGE_ROOT.rglob("*.py"))}


def test_every_top_level_name_has_a_layer() -> None:
    names = {p.stem for p in PACKAGE_ROOT.glob("*.py")} | {
        p.parent.name for p in PACKAGE_ROOT.glob("*/__init__.py")
    }
    assert names - set(LAYERS) == set()


def test_no_import_goes_up_or_sideways() -> None:
    wrong = []
    for module, targets in _graph().items():
        for target, line in targets:
            a, b = _top(module), _top(target)
            if a != b and b != "__init__" and LAYERS[b] >= LAYERS[a]:
                wrong.append(f"{module}:{line} imports {target} ({a}={LAYERS[a]}, {b}={LAYERS[b]})")
    assert wrong == []


def test_no_import_cycle_between_modules() -> None:
    graph = {m: {t for t, _ in ts if t != m} for m, ts in _graph().items()}
    # a package's __init__ re-exporting its own modules is not a cycle of ideas
    for module in graph:
        graph[module] = {t for t in graph[module] if not module.startswith(t + ".")}
    cycles = []
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                cycles.append(" -> ".join([*stack[stack.index(nxt) :], nxt]))
            elif nxt in graph and nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for module in sorted(graph):
        if module not in state:
            visit(module)
    assert cycles == [], cycles


def test_the_checker_sees_an_upward_import(tmp_path: Path) -> None:
    """The walker resolves relative imports, so a back-edge cannot hide behind dots."""
    fake = PACKAGE_ROOT / "archive" / "reprocess.py"
    targets = {t for t, _ in _imports(fake)}
    assert any(t.startswith("protocol_runner.analysis") for t in targets)


def test_docs_architecture_states_the_same_layers() -> None:
    doc = (REPO / "docs" / "architecture.md").read_text(encoding="utf-8")
    stated: dict[str, int] = {}
    for line in doc.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 3 and cells[0].isdigit():
            for name in cells[1].split(","):
                stated[name.strip().strip("`")] = int(cells[0])
    assert stated == LAYERS


def test_readme_links_stay_inside_the_repository() -> None:
    repo = REPO
    readme = (repo / "README.md").read_text(encoding="utf-8")
    targets = re.findall(r"\]\(([^)#]+)", readme) + re.findall(r"`(\.\./[^`]+)`", readme)
    outside = [
        t for t in targets if not t.startswith("http") and not (repo / t).resolve().is_relative_to(repo)
    ]
    missing = [t for t in targets if not t.startswith("http") and not (repo / t).exists()]
    assert outside == [] and missing == []
