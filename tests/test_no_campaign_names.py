"""No campaign's factor or level names in the package: a campaign is a YAML file, never Python.

The names come from the shipped protocols themselves (their `factors:`, or the older `levels:`), so a
new campaign is checked as soon as it is added. Flagged in src/protocol_runner (and the report
templates): a string literal equal to a factor name or to a level label; a Python name equal to a compound
factor name (`brace_rom`); an attribute or keyword equal to any factor name (`st.friction`, `speed=`),
except under hardware/, where one-word names (speed, friction) are the robot's own physics. Level labels
that are bare numbers ("0", "1") or a single character are too common to mean anything and are not
searched.

Names the language itself uses (an element type such as `bungee`, the word `none`) are not campaign
names and are not searched.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import yaml

from protocol_runner.models.element_types import ELEMENT_TYPES

# the source tree of this checkout (the installed copy may be elsewhere: a wheel in site-packages)
REPO = Path(__file__).resolve().parents[1]
PACKAGE_ROOT = REPO / "src" / "protocol_runner"
TEMPLATES = REPO / "reports" / "templates"

#: names a campaign may share with the package's own vocabulary: an element type (the ankle's `bungee`
#: factor sets its bungee element) or a plain word that is also a keyword of the language (`none`)
GENERIC_WORDS = {"none", "all"}


def _campaign_names() -> tuple[set[str], set[str]]:
    factors: set[str] = set()
    labels: set[str] = set()
    for path in sorted((REPO / "protocols").glob("*.yaml")):
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
        if not isinstance(doc, dict):
            continue
        declared = doc.get("factors") or doc.get("levels") or {}
        for factor, levels in declared.items():
            factors.add(str(factor))
            if isinstance(levels, dict):
                labels.update(str(label) for label in levels)
    labels = {label for label in labels if len(label) > 1 and not label.replace(".", "").isdigit()}
    generic = GENERIC_WORDS | set(ELEMENT_TYPES)
    return factors - generic, labels - generic


def _identifiers(node: ast.AST) -> list[tuple[str, int, bool]]:
    """(name, line, is a field: an attribute or keyword) of every Python name in `node`."""
    out: list[tuple[str, int, bool]] = []
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            out.append((sub.id, sub.lineno, False))
        elif isinstance(sub, ast.Attribute):
            out.append((sub.attr, sub.lineno, True))
        elif isinstance(sub, ast.arg):
            out.append((sub.arg, sub.lineno, False))
        elif isinstance(sub, ast.keyword) and sub.arg is not None:
            out.append((sub.arg, sub.value.lineno, True))
    return out


def _python_hits(path: Path, factors: set[str], labels: set[str], *, physics: bool = False) -> list[str]:
    """String literals equal to a factor or label; names equal to a compound factor name (`a_b`); fields
    (attributes, keywords) equal to any factor name, except in the rig's physics (`physics`), where a
    one-word factor name (speed, friction) is the ordinary word for a robot's own quantity."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    hits = []
    for sub in ast.walk(tree):
        if isinstance(sub, ast.Constant) and isinstance(sub.value, str) and sub.value in factors | labels:
            hits.append(f"line {sub.lineno}: string {sub.value!r}")
    for name, line, field in _identifiers(tree):
        if name in factors and ("_" in name or (field and not physics)):
            hits.append(f"line {line}: name {name}")
    return hits


def _template_hits(path: Path, factors: set[str], labels: set[str]) -> list[str]:
    text = path.read_text(encoding="utf-8")
    hits = []
    for name in sorted(factors | labels):
        # a quoted literal ("name" / 'name') or an attribute access (.name)
        pattern = rf"""(["']){re.escape(name)}\1|\.{re.escape(name)}\b"""
        for m in re.finditer(pattern, text):
            hits.append(f"line {text.count(chr(10), 0, m.start()) + 1}: {m.group(0)}")
    return hits


def _all_hits() -> dict[str, list[str]]:
    factors, labels = _campaign_names()
    found: dict[str, list[str]] = {}
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        relative = path.relative_to(PACKAGE_ROOT)
        hits = _python_hits(path, factors, labels, physics=relative.parts[0] == "hardware")
        if hits:
            found[str(relative)] = hits
    for path in sorted(TEMPLATES.glob("*.j2")):
        hits = _template_hits(path, factors, labels)
        if hits:
            found[f"templates/{path.name}"] = hits
    return found


def test_the_shipped_protocols_declare_names_to_search_for() -> None:
    factors, labels = _campaign_names()
    assert len(factors) >= 6 and len(labels) >= 10  # the knee alone: six factors, R1..K-EMU


def test_no_campaign_factor_or_level_name_in_the_package() -> None:
    found = _all_hits()
    assert found == {}, "campaign names in the package (move them to the protocol YAML):\n" + "\n".join(
        f"  {f}: {'; '.join(h[:4])}" for f, h in found.items()
    )


def test_the_scan_finds_a_planted_name(tmp_path: Path) -> None:
    factors, labels = _campaign_names()
    factor, label = sorted(factors)[0], sorted(labels)[0]
    planted = tmp_path / "planted.py"
    planted.write_text(f"def f(cfg):\n    return cfg.{factor}, {label!r}\n", encoding="utf-8")
    hits = _python_hits(planted, factors, labels)
    assert hits == [f"line 2: string {label!r}", f"line 2: name {factor}"]
