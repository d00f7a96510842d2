"""Progress of a session: a rich display on a terminal, plain log lines otherwise, a log file, and the
live monitor's publisher (`--monitor`; a null one otherwise).

Shows the set, configuration and trial, and the ETA in robot time and in wall time.
"""

from __future__ import annotations

import logging
import sys
import time
from pathlib import Path

from ..archive.diskfull import QuietFileHandler
from ..events import NULL_PUBLISHER, Publisher
from ..protocol.plan_steps import CalibrationCheckStep, Plan, Step, TrialStep


def _fmt_s(seconds: float) -> str:
    seconds = max(0.0, seconds)
    if seconds >= 3600:
        return f"{seconds / 3600:.1f} h"
    if seconds >= 60:
        return f"{seconds / 60:.0f} min"
    return f"{seconds:.1f} s"


def describe(step: Step) -> str:
    """Set, configuration and trial of a step, for the progress line."""
    set_name = getattr(step, "set", None)
    parts = [f"set {set_name}"] if set_name else []
    configuration = getattr(step, "configuration", None)
    if configuration is not None:
        parts.append(f"config {configuration}")
    if isinstance(step, TrialStep):
        parts.append(f"trial {step.trial} brace {step.brace}")
    elif isinstance(step, CalibrationCheckStep):
        parts.append(f"calibration check {step.when}")
    else:
        parts.append(step.kind.replace("_", " "))
    return " · ".join(parts)


class Progress:
    def __init__(
        self,
        plan: Plan,
        done: set[str],
        log_path: Path,
        *,
        quiet: bool = False,
        publisher: Publisher = NULL_PUBLISHER,
    ) -> None:
        self.plan = plan
        self.publisher = publisher
        publisher.begin(plan, done)
        self.total_robot_s = sum(s.robot_time_s for s in plan.steps if s.id not in done)
        self.robot_done_s = 0.0
        self.n_total = len(plan.steps)
        self.n_done = len(done & {s.id for s in plan.steps})
        self.t0 = time.monotonic()
        self.logger = logging.getLogger(f"protocol_runner.session.{id(self)}")
        self.logger.setLevel(logging.INFO)
        self.logger.propagate = False
        self._file = QuietFileHandler(log_path, encoding="utf-8")  # a full disk: no traceback per line
        self._file.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        self.logger.addHandler(self._file)
        self.quiet = quiet
        self._rich = None
        self._task = None
        if not quiet and sys.stderr.isatty():
            from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
            from rich.progress import Progress as RichProgress

            self._rich = RichProgress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("{task.fields[eta]}"),
                transient=False,
            )
            self._rich.start()
            self._task = self._rich.add_task("session", total=self.n_total, completed=self.n_done, eta="")

    def _eta(self) -> str:
        remaining_robot = self.total_robot_s - self.robot_done_s
        elapsed = time.monotonic() - self.t0
        wall = elapsed / self.robot_done_s * remaining_robot if self.robot_done_s > 0 else float("nan")
        wall_txt = _fmt_s(wall) if wall == wall else "?"
        return f"ETA robot {_fmt_s(remaining_robot)}, wall {wall_txt}"

    def info(self, message: str) -> None:
        self.logger.info(message)
        if self._rich is not None:
            self._rich.console.print(message)
        elif not self.quiet:
            print(message, file=sys.stderr, flush=True)

    def step_started(self, step: Step) -> None:
        self.logger.info("start %s", step.id)
        self.publisher.step_start(step)
        if self._rich is not None and self._task is not None:
            self._rich.update(self._task, description=describe(step), eta=self._eta())

    def step_finished(self, step: Step, summary: str) -> None:
        """The step's line (its unit is journaled). Lines are numbered as they are printed."""
        self._line(step, summary)

    def _line(self, step: Step, summary: str) -> None:
        self.n_done += 1
        self.robot_done_s += step.robot_time_s
        line = f"[{self.n_done}/{self.n_total}] {step.id}: {summary}  ({self._eta()})"
        self.logger.info(line)
        self.publisher.step_end(step, summary)
        if self._rich is not None and self._task is not None:
            self._rich.update(self._task, completed=self.n_done, eta=self._eta())
            self._rich.console.print(line)
        elif not self.quiet:
            print(line, file=sys.stderr, flush=True)

    def close(self) -> None:
        if self._rich is not None:
            self._rich.stop()
        self.logger.removeHandler(self._file)
        self._file.close()
