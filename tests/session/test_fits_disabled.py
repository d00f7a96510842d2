"""A protocol without the Bouc-Wen fit plans no fit step, and its configurations still end complete."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand

from .conftest import run_dry

REPO = Path(__file__).resolve().parents[2]


def test_without_bouc_wen_configurations_complete(tmp_path: Path) -> None:
    work = tmp_path / "protocols"
    shutil.copytree(REPO / "protocols", work)
    text = (work / "knee_phase1.yaml").read_text()
    edited = text.replace(
        "bouc_wen: {enabled: true, starts: 8, cross_validate: true}", "bouc_wen: {enabled: false}"
    )
    assert edited != text
    (work / "nobw.yaml").write_text(edited)
    plan = expand(load_protocol(work / "nobw.yaml"), only=[12])
    assert not [s for s in plan.steps if s.kind == "fit"]
    session = tmp_path / "s"
    assert run_dry(session, only=[12], protocol=str(work / "nobw.yaml")) == 0
    with h5py.File(session / "archive.h5", "r") as f:
        cfg = f["configurations/config_12"]
        assert cfg.attrs["status"] == "complete"
        assert (
            "bouc_wen" not in cfg["joints/knee_flexion/fits"] and "spring" in cfg["joints/knee_flexion/fits"]
        )
