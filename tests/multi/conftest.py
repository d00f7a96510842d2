"""A dry run of protocols/leg_phase2.yaml (hip, knee and ankle driven together), configurations 1 and 3
(slow gait and sit-to-stand), shared by the tests of what is read from an archive of several joints."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocol_runner.commands import run

REPO = Path(__file__).resolve().parents[2]
LEG = REPO / "protocols" / "leg_phase2.yaml"
LEG_JOINTS = ("hip_flexion", "knee_flexion", "ankle_flexion")


@pytest.fixture(scope="session")
def leg_archive(tmp_path_factory: pytest.TempPathFactory) -> Path:
    session = tmp_path_factory.mktemp("leg") / "session"
    code = run(
        str(LEG), dry_run=True, session=session, seed=7, yes=True, only=[1, 3], realtime=False, quiet=True
    )
    assert code == 0
    return session / "archive.h5"
