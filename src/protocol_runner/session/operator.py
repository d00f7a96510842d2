"""Operator prompts: the checklists a person works through at the rig, and decisions on failed checks.

`AutoOperator` answers for a dry run or `--yes` (checklists done; a failed calibration check is NOT
accepted automatically: safety first). `ConsoleOperator` asks on the terminal with rich.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Protocol

from ..errors import Interrupted, InvalidInput
from ..protocol.plan import ChecklistStep
from .journal import utc_now


@dataclass(frozen=True)
class Answer:
    answer: str  # "done"
    answered_utc: str
    automatic: bool


class Operator(Protocol):
    def checklist(self, step: ChecklistStep) -> Answer: ...

    def accept_failed_check(self, message: str) -> bool: ...

    def confirm(self, question: str) -> bool: ...


class AutoOperator:
    """Answers every checklist as done; refuses failed checks (they stop the session, exit 4)."""

    def checklist(self, step: ChecklistStep) -> Answer:
        return Answer("done", utc_now(), automatic=True)

    def accept_failed_check(self, message: str) -> bool:
        return False

    def confirm(self, question: str) -> bool:
        return True


class ConsoleOperator:
    """Asks on the terminal. Without a terminal it refuses to guess: use --yes or --dry-run."""

    def __init__(self) -> None:
        if not sys.stdin.isatty():
            raise InvalidInput("operator prompts need a terminal; answer them automatically with --yes")
        from rich.console import Console

        self.console = Console(stderr=True)

    def _ask(self, question: str, *, default: str | None = None) -> str:
        from rich.prompt import Prompt

        try:
            if default is None:
                return Prompt.ask(question, choices=["y", "n", "q"], console=self.console)
            return Prompt.ask(question, choices=["y", "n", "q"], default=default, console=self.console)
        except EOFError:
            raise Interrupted("no answer from the operator (end of input)") from None

    def checklist(self, step: ChecklistStep) -> Answer:
        from rich.panel import Panel

        body = "\n".join(f"[ ] {item}" for item in step.items)
        while True:
            self.console.print(Panel(body, title=step.title, subtitle=step.id))
            reply = self._ask("All done? (y = done, n = show again, q = stop here, resumable)", default="y")
            if reply == "y":
                return Answer("done", utc_now(), automatic=False)
            if reply == "q":
                raise Interrupted(f"stopped by the operator at {step.id}")

    def accept_failed_check(self, message: str) -> bool:
        self.console.print(f"[bold red]{message}[/]")
        reply = self._ask("Accept this result and continue? (y/n; q = stop here, resumable)")
        if reply == "q":
            raise Interrupted("stopped by the operator after a failed calibration check")
        return reply == "y"

    def confirm(self, question: str) -> bool:
        reply = self._ask(question + " (y/n; q = stop, resumable)")
        if reply == "q":
            raise Interrupted("stopped by the operator")
        return reply == "y"
