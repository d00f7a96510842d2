"""No code guards against modules that have landed: a broken import must fail loudly, not be skipped."""

from __future__ import annotations

import ast
from pathlib import Path

# the source tree of this checkout (the installed copy may be elsewhere: a wheel in site-packages)
REPO = Path(__file__).resolve().parents[1]
PACKAGE_ROOT = REPO / "src" / "protocol_runner"


def _handlers() -> list[str]:
    found = []
    for path in sorted(PACKAGE_ROOT.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.ExceptHandler) and node.type is not None:
                names = node.type.elts if isinstance(node.type, ast.Tuple) else [node.type]
                if any(
                    isinstance(n, ast.Name) and n.id in {"ImportError", "ModuleNotFoundError"} for n in names
                ):
                    found.append(f"{path.relative_to(PACKAGE_ROOT)}:{node.lineno}")
    return found


def test_no_import_error_is_swallowed() -> None:
    assert _handlers() == []


def test_hardware_check_exits_3_when_no_board_is_found(monkeypatch, capsys) -> None:
    from protocol_runner import commands
    from protocol_runner.hardware import discovery

    empty = discovery.HardwareReport(boards=(), problems=(), checks=())
    monkeypatch.setattr(discovery, "hardware_check", lambda required=None, timing=None: empty)
    assert commands.hardware_check(None) == 3
    assert "NOT ready" in capsys.readouterr().out
