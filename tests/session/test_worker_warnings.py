"""A warning raised in an analysis worker does not vanish on the worker's stderr: it travels back with
its step and is written on the step's line in session.log and the progress output, in full the first time
the session meets that kind of warning."""

from __future__ import annotations

import warnings
from concurrent.futures import Future
from pathlib import Path
from types import SimpleNamespace
from typing import Any

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import ProcessStep, expand
from protocol_runner.session import workers
from protocol_runner.session.progress import Progress
from protocol_runner.steps.context import StepOutcome

KNEE = Path(__file__).resolve().parents[2] / "protocols" / "knee_phase1.yaml"


def overflowing_step(step: Any, ctx: Any) -> StepOutcome:
    for _ in range(3):
        warnings.warn("overflow encountered in power", RuntimeWarning, stacklevel=1)
    return StepOutcome(None, f"{step.id} done")


def test_a_workers_warning_reaches_the_session_log_once_in_full(monkeypatch: Any, tmp_path: Path) -> None:
    loaded = load_protocol(KNEE)
    plan = expand(loaded)
    first, second = [s for s in plan.steps if isinstance(s, ProcessStep)][:2]
    monkeypatch.setattr(workers, "run_step", overflowing_step)
    # what a worker's task returns (run in this process: the warnings filter is the test suite's)
    results = [workers.run_analysis_steps(loaded, plan, tmp_path, (s.id,)) for s in (first, second)]
    line_no = overflowing_step.__code__.co_firstlineno + 2
    kind = f"RuntimeWarning: overflow encountered in power ({_here()}:{line_no})"
    assert results[0] == [(None, f"{first.id} done", ((kind, 3),))]

    pool = workers.AnalysisPool(loaded, plan, tmp_path, SimpleNamespace(units={}))  # type: ignore[arg-type]
    for step, result in zip((first, second), results, strict=True):
        future: Future[workers.Results] = Future()
        future.set_result(result)
        pool._pending.append(((step,), future))
    log = tmp_path / "session.log"
    progress = Progress(plan, set(), log, quiet=True)
    pool.collect(progress.step_finished)
    progress.close()
    lines = log.read_text(encoding="utf-8").splitlines()
    assert any(
        f"{first.id}: {first.id} done; WARNING RuntimeWarning: overflow encountered in power" in line
        and "(3 times)" in line
        for line in lines
    )
    assert any(
        f"{second.id}: {second.id} done; WARNING RuntimeWarning again (3 times)" in line for line in lines
    )


def _here() -> str:
    return "/".join(Path(__file__).parts[-3:])
