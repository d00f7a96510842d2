"""The analysis workers started by "spawn" (where there is no fork server) run the analyses exactly as
those forked from the fork server: everything a worker runs is a module-level function and every argument
is pickled, nothing is inherited from the session's memory."""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import pytest

from protocol_runner.session import workers

from .conftest import assert_same_data, run_dry


def test_spawned_workers_give_the_same_archive(
    reference_archive: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    started: list[str] = []

    def spawn() -> multiprocessing.context.BaseContext:
        started.append("spawn")
        return multiprocessing.get_context("spawn")

    monkeypatch.setattr(workers, "worker_context", spawn)
    session = tmp_path / "s"
    assert run_dry(session) == 0
    assert started  # the analyses did run on spawned workers
    assert_same_data(reference_archive, session / "archive.h5")
