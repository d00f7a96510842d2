"""Fixtures for the report tests: small synthetic archives laid out as docs/archive.md says."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.report.render import generate_report
from tests.report.report_archive_builder import small_spec, write_archive


@pytest.fixture(scope="session")
def small_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A complete session's archive (do not modify: shared by the whole test session)."""
    folder = tmp_path_factory.mktemp("small")
    return write_archive(folder / "archive.h5", small_spec())


@pytest.fixture(scope="session")
def small_report(small_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> str:
    """The HTML report of `small_archive`."""
    out = tmp_path_factory.mktemp("small_report") / "report.html"
    generate_report(small_archive, out)
    return out.read_text(encoding="utf-8")
