"""`--export` of an archive of several joints: every table has a row per joint, each from that joint's own
data, and the same `joint` names as the model tables (docs/report.md "Tables")."""

from __future__ import annotations

import csv
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.report.headline import configuration_stats
from protocol_runner.report.load import load_report_data
from protocol_runner.report.tidy import export_tables

from .conftest import LEG_JOINTS


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module")
def tables(leg_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("leg_tables")
    export_tables(leg_archive, out)
    return out


def test_cycles_and_trials_are_each_joints_own(leg_archive: Path, tables: Path) -> None:
    cycles, trials = _rows(tables / "cycles.csv"), _rows(tables / "trials.csv")
    with h5py.File(leg_archive, "r") as f:
        for key in (1, 3):
            for joint in LEG_JOINTS:
                part = f[f"configurations/config_{key:02d}/joints/{joint}"]
                own = [r for r in cycles if int(r["configuration"]) == key and r["joint"] == joint]
                assert [float(r["energy_j"]) for r in own] == part["energy_loss_j"][()].tolist()
                assert [int(r["trial"]) for r in own] == part["energy_cycle_trial"][()].tolist()
                for r in (r for r in trials if int(r["configuration"]) == key and r["joint"] == joint):
                    angle = part[f"trials/{r['trial']}/processed/angle_deg"][()]
                    assert (float(r["angle_min_deg"]), float(r["angle_max_deg"])) == (
                        angle.min(),
                        angle.max(),
                    )
    # the hip's own range (about 30 deg) is not the knee's (about 55) in the same trial
    first = {r["joint"]: r for r in trials if r["configuration"] == "1" and r["trial"] == "1"}
    hip, knee = (float(first[j]["angle_max_deg"]) - float(first[j]["angle_min_deg"]) for j in LEG_JOINTS[:2])
    assert 20 < hip < 40 < knee < 70


def test_configurations_have_a_row_per_joint_with_the_reports_numbers(
    leg_archive: Path, tables: Path
) -> None:
    rows = _rows(tables / "configurations.csv")
    assert [(r["configuration"], r["joint"]) for r in rows] == [
        (str(k), j) for k in (1, 3) for j in LEG_JOINTS
    ]
    data = load_report_data(leg_archive, workers=1)
    for row in rows:
        cfg = data.configuration(int(row["configuration"]), row["joint"])
        assert cfg is not None
        s = configuration_stats(cfg)
        assert float(row["energy_mean_j"]) == pytest.approx(s.energy.mean, rel=1e-12)
        assert int(row["trials"]) == s.trials == 3
        assert row["motion"] == cfg.level("motion")


def test_the_joint_column_agrees_with_the_model_tables(tables: Path) -> None:
    models = {(r["configuration"], r["joint"]) for r in _rows(tables / "models.csv")}
    configurations = {(r["configuration"], r["joint"]) for r in _rows(tables / "configurations.csv")}
    # the model comparison runs on the joints that carry elements: the knee and the ankle
    assert models == {(k, j) for k in ("1", "3") for j in ("knee_flexion", "ankle_flexion")}
    assert models < configurations
    assert np.all([r["joint"] in LEG_JOINTS for r in _rows(tables / "elements.csv")])
