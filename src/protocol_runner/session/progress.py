"""Progress of a session: a rich display on a terminal, plain log lines otherwise, a log file, and the
live monitor's publisher (`--monitor`).

Shows the set, configuration and trial, and the ETA in robot and wall time. Every line shown is in
`session.log` too, so a line that cannot be shown is dropped from the screen (`streams.py`). While an
operator prompt waits on the terminal, the live display is paused (`display_paused`) so that it does not
draw over the question.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from ..archive.diskfull import QuietFileHandler
from ..events import NULL_PUBLISHER, Publisher
from ..protocol.plan_steps import CalibrationCheckStep, Plan, Step, TrialStep
from .lock import open_nofollow
from .streams import say

_LIVE: list[Progress] = []  # the displays drawing on this process's terminal (one per running session)


@contextlib.contextmanager
def display_paused() -> Iterator[None]:
    """Stop the live progress display while a prompt is on the terminal; redraw it after."""
    paused = [p for p in _LIVE if p._rich is not None]
    for p in paused:
        p._pause()
    try:
        yield
    finally:
        for p in paused:
            p._resume()


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
        # (wall clock, robot time done) once the first step is done: the ETA's rate is learnt from there
        self._rate_from: tuple[float, float] | None = None
        self.logger = logging.getLogger(f"protocol_runner.session.{id(self)}")
        self.logger.setLevel(logging.INFO)
        self.logger.propagate = False
        os.close(open_nofollow(log_path, os.O_WRONLY | os.O_CREAT | os.O_APPEND))  # never through a link
        self._file = QuietFileHandler(log_path, encoding="utf-8")  # a full disk: no traceback per line
        self._file.setFormatter(logging.Formatter("%(asctime)s %(message)s"))
        self.logger.addHandler(self._file)
        self.quiet = quiet
        self._rich: Any = None
        self._task = None
        if not quiet and sys.stderr is not None and sys.stderr.isatty():
            from rich.console import Console
            from rich.progress import BarColumn, MofNCompleteColumn, TextColumn, TimeElapsedColumn
            from rich.progress import Progress as RichProgress

            self._rich = RichProgress(
                TextColumn("[bold]{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("{task.fields[eta]}"),
                console=Console(stderr=True),  # progress and prompts are on standard error
                transient=False,
            )
            self._task = self._rich.add_task("session", total=self.n_total, completed=self.n_done, eta="")
            self._resume()
            _LIVE.append(self)

    def _pause(self) -> None:
        with contextlib.suppress(OSError, ValueError):  # the terminal is gone: nothing to stop drawing on
            self._rich.stop()

    def _resume(self) -> None:
        try:
            self._rich.start()
        except (OSError, ValueError):
            self._gone()

    def _gone(self) -> None:
        """The terminal went away: no more display; the lines go on in session.log."""
        if self._rich is not None:
            self._pause()
            self._rich = None
            self.logger.info("the terminal is gone: progress is in this log only")

    def _show(self, line: str) -> None:
        if self._rich is not None:
            try:
                self._rich.console.print(line, markup=False, highlight=False)
            except (OSError, ValueError):
                self._gone()
        elif not self.quiet:
            say(line)

    def _eta(self) -> str:
        """Robot time left, and the wall time it will take at the wall-per-robot-second rate of the steps
        finished after this process's first (which includes the one-time start-up: compiling the
        simulator's kernels); "?" until that rate is known."""
        remaining_robot = self.total_robot_s - self.robot_done_s
        wall = float("nan")
        if self._rate_from is not None and self.robot_done_s > self._rate_from[1]:
            t_from, robot_from = self._rate_from
            wall = (time.monotonic() - t_from) / (self.robot_done_s - robot_from) * remaining_robot
        wall_txt = _fmt_s(wall) if wall == wall else "?"
        return f"ETA robot {_fmt_s(remaining_robot)}, wall {wall_txt}"

    def info(self, message: str) -> None:
        self.logger.info(message)
        self._show(message)

    def step_started(self, step: Step) -> None:
        self.logger.info("start %s", step.id)
        self.publisher.step_start(step)
        if self._rich is not None and self._task is not None:
            self._rich.update(self._task, description=describe(step), eta=self._eta())

    def step_finished(self, step: Step, summary: str) -> None:
        """The step's line (its unit is journaled). Lines are numbered as they are printed."""
        self.n_done += 1
        self.robot_done_s += step.robot_time_s
        if self._rate_from is None:  # the rate is learnt from the steps after this first one
            self._rate_from = (time.monotonic(), self.robot_done_s)
        line = f"[{self.n_done}/{self.n_total}] {step.id}: {summary}  ({self._eta()})"
        self.logger.info(line)
        self.publisher.step_end(step, summary)
        if self._rich is not None and self._task is not None:
            self._rich.update(self._task, completed=self.n_done, eta=self._eta())
        self._show(line)

    def close(self) -> None:
        if self in _LIVE:
            _LIVE.remove(self)
        if self._rich is not None:
            self._pause()
        self.logger.removeHandler(self._file)
        self._file.close()
