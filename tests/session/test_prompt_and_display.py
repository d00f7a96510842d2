"""Operator prompts on a terminal and the live progress display; a hardware run that cannot prompt.

- While a question waits for the operator's answer, the progress display draws nothing (it redraws about
  ten times a second and used to erase the checklist question and the operator's typing), and it is
  running again once the question is answered.
- A hardware run without a terminal and without --yes is refused before anything is created: no session
  folder is left behind, and the DAQ boards opened to check them are closed again."""

from __future__ import annotations

import io
import sys
import threading
import time
from pathlib import Path

import pytest
from rich.console import Console

from protocol_runner import commands
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import ChecklistStep, expand
from protocol_runner.session import rigs
from protocol_runner.session.operator import ConsoleOperator
from protocol_runner.session.progress import Progress


class Terminal(io.StringIO):
    """Standard error as a terminal: what the live display draws on it accumulates here."""

    def __init__(self) -> None:
        super().__init__()
        self.lock = threading.Lock()

    def isatty(self) -> bool:
        return True

    def write(self, text: str) -> int:
        with self.lock:
            return super().write(text)

    def drawn(self) -> int:
        with self.lock:
            return len(self.getvalue())


class Operator:
    """Types its answer once the display has drawn something more on the terminal, or after 2 s."""

    def __init__(self, terminal: Terminal) -> None:
        self.terminal = terminal
        self.drawn_while_asked: list[int] = []

    def readline(self) -> str:
        before = self.terminal.drawn()
        deadline = time.monotonic() + 2.0
        while self.terminal.drawn() == before and time.monotonic() < deadline:
            time.sleep(0.01)
        self.drawn_while_asked.append(self.terminal.drawn() - before)
        return "y\n"


def test_the_display_never_draws_over_a_question_waiting_for_its_answer(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    monkeypatch.setattr(sys, "stdout", terminal)  # the same terminal, as in a shell
    plan = expand(load_protocol(find_protocol("elbow_example.yaml")))
    progress = Progress(plan, set(), tmp_path / "session.log")
    typing = Operator(terminal)
    try:
        op = ConsoleOperator(console=Console(file=io.StringIO(), width=120), stdin=typing)  # type: ignore[arg-type]
        step = ChecklistStep(
            id="check:x", kind="operator_checklist", set="s", title="t", items=("a",), brace="on"
        )
        assert op.checklist(step).answer == "done"
        assert op.accept_failed_check("calibration check failed")
        assert typing.drawn_while_asked == [0, 0]
        assert progress._rich is not None and progress._rich.live.is_started  # drawn again after
    finally:
        progress.close()


class Boards:
    open = 0

    def __init__(self, loaded: object) -> None:
        Boards.open += 1

    def close(self) -> None:
        Boards.open -= 1


def test_a_hardware_run_that_cannot_prompt_is_refused_before_anything_is_created(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(rigs, "HardwareBench", Boards)
    monkeypatch.setattr(sys, "stdin", io.StringIO(""))  # no terminal
    session = tmp_path / "sessions" / "s"
    with pytest.raises(InvalidInput, match="--yes"):
        commands.run(
            "elbow_example.yaml",
            dry_run=False,
            session=session,
            seed=None,
            yes=False,
            only=None,
            realtime=False,
            quiet=True,
        )
    assert not session.exists() and not session.parent.exists()
    assert Boards.open == 0
