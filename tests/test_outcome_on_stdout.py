"""Every command's outcome goes to standard output and its messages to standard error (docs/session.md):
`--report`, `--export` and `--compare` printed theirs on standard error, so `... > out` kept nothing."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.cli import main
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive


@pytest.fixture(scope="module")
def archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("outcome")
    configs = [ConfigSpec(key=k, energy_j=2.0, n_trials=3) for k in (4, 5)]
    return write_archive(folder / "archive.h5", ArchiveSpec(configs=configs, duration_s=17.0, seed=3))


def test_report_export_and_compare_print_their_outcome_on_stdout(
    archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--report", str(archive), "--output", str(tmp_path / "r.html")]) == 0
    out, err = capsys.readouterr()
    assert out == f"report: {tmp_path / 'r.html'}\n" and "report:" not in err
    assert main(["--export", str(archive), "--output", str(tmp_path / "t")]) == 0
    out, err = capsys.readouterr()
    tables = "cycles.csv, trials.csv, configurations.csv, models.csv, elements.csv, predictions.csv"
    assert out == f"wrote {tables} to {tmp_path / 't'}\n", out
    assert "wrote" not in err
    assert main(["--compare", str(archive), str(archive), "--output", str(tmp_path / "c.html")]) == 0
    out, err = capsys.readouterr()
    assert out.splitlines()[-1] == f"comparison: {tmp_path / 'c.html'}" and len(out.splitlines()) > 2
    assert "comparison:" not in err
