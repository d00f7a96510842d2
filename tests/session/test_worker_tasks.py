"""An analysis worker receives the session's protocol and plan once, when it starts, and each task only
names its steps (session/workers.py): the knee's protocol and plan are 0.16 MB pickled, which every one of
its 28 tasks would otherwise carry."""

from __future__ import annotations

import pickle
from concurrent.futures import Future
from pathlib import Path
from types import SimpleNamespace
from typing import Any, ClassVar

from protocol_runner.protocol.loaded import LoadedProtocol
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import Plan, ProcessStep
from protocol_runner.session import workers

KNEE = Path(__file__).resolve().parents[2] / "protocols" / "knee_phase1.yaml"


class _RecordingPool:
    """A ProcessPoolExecutor that records how it was started and what it was given."""

    made: ClassVar[list[_RecordingPool]] = []

    def __init__(
        self, max_workers: int, mp_context: Any, initializer: Any, initargs: tuple[Any, ...]
    ) -> None:
        self.initializer, self.initargs = initializer, initargs
        self.tasks: list[tuple[Any, tuple[Any, ...]]] = []
        _RecordingPool.made.append(self)

    def submit(self, fn: Any, *args: Any) -> Future[Any]:
        self.tasks.append((fn, args))
        return Future()


def test_the_protocol_and_plan_reach_a_worker_once_and_its_tasks_use_them(
    monkeypatch: Any, tmp_path: Path
) -> None:
    loaded = load_protocol(KNEE)
    plan = expand(loaded)
    monkeypatch.setattr(workers, "ProcessPoolExecutor", _RecordingPool)
    pool = workers.AnalysisPool(loaded, plan, tmp_path, SimpleNamespace(units={}))  # type: ignore[arg-type]
    processes = [s for s in plan.steps if isinstance(s, ProcessStep)][:3]
    for step in processes:
        pool.submit(step)
    (made,) = _RecordingPool.made[-1:]
    assert made.initargs == (loaded, plan)
    assert len(made.tasks) == 3
    for _fn, args in made.tasks:
        assert not any(isinstance(a, (LoadedProtocol, Plan)) for a in args)
        assert len(pickle.dumps(args)) < 1_000 < len(pickle.dumps((loaded, plan)))

    # in a worker started so, a task runs its steps with that protocol and plan
    ran: list[tuple[Any, ...]] = []
    monkeypatch.setattr(workers, "worker_init", lambda: None)  # not this test process's signals
    monkeypatch.setattr(workers, "run_analysis_steps", lambda *a: ran.append(a) or [])
    made.initializer(*pickle.loads(pickle.dumps(made.initargs)))
    fn, args = made.tasks[0]
    assert fn(*args) == []
    (got,) = ran
    assert got[0] == loaded and got[1].steps == plan.steps
    assert got[2:] == (tmp_path, (processes[0].id, f"fit:k{processes[0].configuration:02d}"))
