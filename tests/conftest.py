"""Shared fixtures: one uninterrupted reference dry run (session scope) that several test folders compare with."""

from __future__ import annotations

from pathlib import Path

import pytest

from .session.conftest import run_dry


@pytest.fixture(scope="session")
def reference_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    session = tmp_path_factory.mktemp("reference") / "session"
    assert run_dry(session) == 0
    return session / "archive.h5"
