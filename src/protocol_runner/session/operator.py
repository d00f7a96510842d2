"""Operator prompts: the checklists a person works through at the rig, and decisions on failed checks.

`AutoOperator` answers for a dry run or `--yes` (a failed calibration check is NOT accepted automatically:
safety first). `ConsoleOperator` asks on the terminal, the live progress display paused meanwhile.
"""

from __future__ import annotations

import sys
from typing import Any, TextIO

from ..errors import Interrupted, InvalidInput
from ..protocol.plan_steps import ChecklistStep
from ..steps.operator import Answer
from .journal import utc_now
from .progress import display_paused

ANSWERS = {"y": "y", "yes": "y", "n": "n", "no": "n", "q": "q", "quit": "q"}  # nothing else counts


class AutoOperator:
    """Answers every checklist as done; refuses failed checks (they stop the session, exit 4)."""

    def checklist(self, step: ChecklistStep) -> Answer:
        return Answer("done", utc_now(), automatic=True)

    def accept_failed_check(self, message: str) -> bool:
        return False


class ConsoleOperator:
    """Asks on the terminal (without one it refuses to guess). Text from the protocol is shown exactly as
    written (never read as rich markup), and only an explicit y, n or q answers: Enter alone asks again."""

    def __init__(self, console: Any = None, stdin: TextIO | None = None) -> None:
        if stdin is None and not sys.stdin.isatty():
            raise InvalidInput("operator prompts need a terminal; answer them automatically with --yes")
        from rich.console import Console

        self.console = console if console is not None else Console(stderr=True)
        self.stdin = stdin if stdin is not None else sys.stdin

    def _ask(self, question: str) -> str:
        """An explicit y/n/q; anything else (Enter alone included) asks again. End of input stops."""
        while True:
            self.console.print(question + " ", end="", markup=False, highlight=False)
            line = self.stdin.readline()
            if not line:
                raise Interrupted("no answer from the operator (end of input)")
            reply = ANSWERS.get(line.strip().lower())
            if reply is not None:
                return reply
            self.console.print("Please answer y, n or q.", markup=False, highlight=False)

    def checklist(self, step: ChecklistStep) -> Answer:
        from rich.panel import Panel
        from rich.text import Text

        body = Text("\n".join(f"[ ] {item}" for item in step.items))
        with display_paused():
            while True:
                self.console.print(Panel(body, title=Text(step.title), subtitle=Text(step.id)))
                reply = self._ask("All done? (y = done, n = show again, q = stop here, resumable)")
                if reply == "y":
                    return Answer("done", utc_now(), automatic=False)
                if reply == "q":
                    raise Interrupted(f"stopped by the operator at {step.id}")

    def accept_failed_check(self, message: str) -> bool:
        from rich.text import Text

        with display_paused():
            self.console.print(Text(message, style="bold red"))
            reply = self._ask("Accept this result and continue? (y/n; q = stop here, resumable)")
        if reply == "q":
            raise Interrupted("stopped by the operator after a failed calibration check")
        return reply == "y"
