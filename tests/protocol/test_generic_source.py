"""No campaign lives in the package: the knee campaign's factor names and level labels are data
(protocols/knee_phase1.yaml), never a string or an identifier in src/ (issue 11)."""

from __future__ import annotations

import ast
from pathlib import Path

import yaml

REPO = Path(__file__).resolve().parents[2]
PACKAGE = REPO / "src" / "protocol_runner"
KNEE = REPO / "protocols" / "knee_phase1.yaml"
# physical words a campaign may also use as a factor name (the ankle's bungee/brake/stops are element
# types or plain words; the knee's `speed` is every trajectory's speed)
GENERIC_WORDS = {"speed"}
# report/ belongs to the report's own migration (helper REPORT, issue 11); it is scanned once it lands
NOT_YET = ("report",)


def campaign_names() -> set[str]:
    names: set[str] = set()
    data = yaml.safe_load(KNEE.read_text(encoding="utf-8"))
    for factor, levels in data["factors"].items():
        names.add(factor)
        names.update(str(label) for label in levels if len(str(label)) > 2)  # "0", "K2": too short
    return names - GENERIC_WORDS


def identifiers_and_strings(tree: ast.AST) -> set[str]:
    docstrings = {
        id(node.body[0].value)
        for node in ast.walk(tree)
        if isinstance(node, ast.Module | ast.ClassDef | ast.FunctionDef | ast.AsyncFunctionDef)
        and node.body
        and isinstance(node.body[0], ast.Expr)
        and isinstance(node.body[0].value, ast.Constant)
    }
    modules = {a.asname or a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            found.add(node.value)
        elif isinstance(node, ast.Name):
            found.add(node.id)
        elif isinstance(node, ast.Attribute):
            if not (isinstance(node.value, ast.Name) and node.value.id in modules):  # queue.Full: a library's
                found.add(node.attr)
        elif isinstance(node, ast.arg) or (isinstance(node, ast.keyword) and node.arg):
            found.add(node.arg)
    return found


def test_the_scan_sees_the_campaign_names() -> None:
    names = campaign_names()
    assert {"brace_rom", "robot_rom", "friction", "stiffness", "preload", "Center", "K-EMU", "Rr3"} <= names


def test_no_campaign_factor_or_level_name_in_the_package() -> None:
    names = campaign_names()
    hits = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE)
        if rel.parts[0] in NOT_YET:
            continue
        for name in identifiers_and_strings(ast.parse(path.read_text(encoding="utf-8"))) & names:
            hits.append(f"{rel}: {name}")
    assert hits == []
