"""Operator prompts on the terminal: protocol text is shown exactly as written (rich
markup is never interpreted), and a physical confirmation needs an explicit answer: Enter alone is no "yes"."""

from __future__ import annotations

import io

import pytest
from rich.console import Console

from protocol_runner.errors import Interrupted
from protocol_runner.protocol.plan_steps import ChecklistStep
from protocol_runner.session.operator import ConsoleOperator

ITEMS = (
    "Fit both springs: [K3] = 20 N/mm",
    "Set the brake [/] exactly 0.75 turns",
    "[bold]not bold[/bold] and [red]not red[/]",
)


def operator(typed: str) -> tuple[ConsoleOperator, io.StringIO]:
    shown = io.StringIO()
    return ConsoleOperator(console=Console(file=shown, width=200), stdin=io.StringIO(typed)), shown


def checklist() -> ChecklistStep:
    return ChecklistStep(
        id="check:s:k01",
        kind="operator_checklist",
        set="s",
        title="Set up [brace] k1",
        items=ITEMS,
        brace="on",
    )


def test_checklist_text_is_shown_exactly_as_written() -> None:
    op, shown = operator("y\n")
    assert op.checklist(checklist()).answer == "done"
    text = shown.getvalue()
    for item in ITEMS:
        assert f"[ ] {item}" in text
    assert "Set up [brace] k1" in text


def test_enter_alone_is_not_an_answer() -> None:
    op, shown = operator("\n\n  \nmaybe\ny\n")
    answer = op.checklist(checklist())
    assert answer.answer == "done" and answer.automatic is False
    assert shown.getvalue().count("Please answer y, n or q.") == 4


def test_enter_alone_then_end_of_input_stops_instead_of_confirming() -> None:
    op, _ = operator("\n")
    with pytest.raises(Interrupted):
        op.checklist(checklist())


def test_q_stops_and_n_shows_the_list_again() -> None:
    op, shown = operator("n\nq\n")
    with pytest.raises(Interrupted, match="check:s:k01"):
        op.checklist(checklist())
    assert shown.getvalue().count(ITEMS[0]) == 2


def test_failed_check_message_with_brackets_is_shown_and_needs_an_answer() -> None:
    op, shown = operator("\nn\n")
    assert op.accept_failed_check("tau [0.3, 0.35] s: 0.21 s [/]") is False
    assert "tau [0.3, 0.35] s: 0.21 s [/]" in shown.getvalue()
