"""Worker processes: results in order, errors propagate, and a pool that cannot start falls back to serial."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.report import parallel
from protocol_runner.report.figure_plan import figure_ids
from protocol_runner.report.figures import assemble_figures
from protocol_runner.report.load import load_report_data


def _square(x: int) -> int:
    return x * x


def _fail_on_three(x: int) -> int:
    if x == 3:
        raise ValueError("three")
    return x


def test_results_come_back_in_input_order() -> None:
    assert parallel.map_in_processes(_square, range(20), 2, chunksize=3) == [x * x for x in range(20)]


def test_a_worker_exception_reaches_the_caller() -> None:
    with pytest.raises(ValueError, match="three"):
        parallel.map_in_processes(_fail_on_three, range(6), 2)


def test_without_worker_processes_the_report_is_read_and_drawn_serially(
    small_archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    def no_processes(*args: object, **kwargs: object) -> object:
        raise OSError("cannot start a process here")

    monkeypatch.setattr(parallel, "ProcessPoolExecutor", no_processes)
    assert parallel.map_in_processes(_square, [1, 2], 2) is None
    data = load_report_data(small_archive, workers=2)
    figures = assemble_figures(data, 2)
    assert figures.missing == {} and set(figures.images) == set(figure_ids(data))
