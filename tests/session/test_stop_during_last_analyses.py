"""A Ctrl-C that lands while the session waits for its last analyses (the rig's work all done) stops the
session before its report, as the message "stopping at the next safe point" announces: exit as
interrupted, the analyses that finished kept, the report written by the resume. (A fast dry run spends
most of its end there, so a stop there must not be swallowed by a run that then completes.)"""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from protocol_runner.commands import resume
from protocol_runner.errors import Interrupted
from protocol_runner.session import runner as runner_module
from protocol_runner.session import workers
from protocol_runner.session.journal import Journal
from protocol_runner.session.signals import StopFlag

from .conftest import run_dry


def test_a_stop_while_the_last_analyses_run_stops_before_the_report(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "s"
    flag = StopFlag()
    real_collect = workers.AnalysisPool.collect

    def collect(self: workers.AnalysisPool, finished, *, wait: bool = False) -> None:  # type: ignore[no-untyped-def]
        real_collect(self, finished, wait=wait)
        if wait:  # the session waited for its last analyses: Ctrl-C meanwhile
            flag.request("SIGINT")

    with monkeypatch.context() as m:
        m.setattr(workers.AnalysisPool, "collect", collect)
        m.setattr(runner_module, "StopFlag", lambda: flag)
        with pytest.raises(Interrupted) as info:
            run_dry(session)
    assert "--resume" in info.value.message
    assert not (session / "report.html").exists()
    units = set(Journal(session / "journal.jsonl").units)
    assert {"process:k12", "fit:k12"} <= units  # the analyses that finished are kept
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "incomplete"
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert (session / "report.html").is_file()
    assert set(Journal(session / "journal.jsonl").units) == units  # nothing redone, nothing lost
    kinds = [json.loads(line).get("kind") for line in (session / "journal.jsonl").read_text().splitlines()]
    assert "interrupted" in kinds
