"""The statistics rows of a configuration (report/headline.py): each joint's, then with several joints all
joints' together, which the campaign-level numbers use; hand-made energies whose means are known."""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from protocol_runner.report.headline import ALL_JOINTS, campaign_stats, headline_stats
from protocol_runner.report.model import Configuration, JointsTotal, ReportData, SessionInfo
from tests.report.test_evaluate import cfg


def joint_part(joint: str, energies: list[float], angles: tuple[float, float]) -> Configuration:
    """Configuration 1's part for `joint`: trial t has one cycle of energy energies[t]."""
    return dataclasses.replace(
        cfg(1, energies), joint=joint, angle_min_deg=angles[0], angle_max_deg=angles[1]
    )


def report(parts: tuple[Configuration, ...], totals: tuple[JointsTotal, ...]) -> ReportData:
    joints = tuple(p.joint for p in parts)
    session = SessionInfo("a.h5", "p", "", 2, "", "dry-run", 0, "", "", "complete", ",".join(joints), ())
    return ReportData(session, parts, (), (), joints=joints, totals=totals)


HIP = joint_part("hip", [1.0, 1.2, 1.4], (10.0, 50.0))
KNEE = joint_part("knee", [2.0, 2.4, 2.2], (5.0, 95.0))
TOTAL = JointsTotal(
    key=1, energy_loss_j=np.array([3.0, 3.6, 3.6]), energy_cycle_trial=np.array([1.0, 2.0, 3.0])
)


def test_each_joint_has_its_row_and_all_joints_together_come_last() -> None:
    rows = headline_stats(report((HIP, KNEE), (TOTAL,)), 1)
    assert [r.joint for r in rows] == ["hip", "knee", ALL_JOINTS]
    assert [r.energy.mean for r in rows] == [1.2, 2.2, 3.4]
    assert (rows[0].angle_min_deg, rows[0].angle_max_deg) == (10.0, 50.0)
    assert math.isnan(rows[2].angle_min_deg) and math.isnan(rows[2].angle_max_deg)  # each joint has its own


def test_the_campaign_uses_all_joints_together_or_nothing_and_one_joint_its_own_row() -> None:
    several = report((HIP, KNEE), (TOTAL,))
    together = campaign_stats(several, 1)
    assert together is not None and together.joint == ALL_JOINTS and together.energy.mean == 3.4
    for parts in ((HIP, KNEE), (KNEE, dataclasses.replace(HIP, joint="abduction"))):  # "ab..." < "all joints"
        assert campaign_stats(report(parts, ()), 1) is None  # no total recorded: no campaign number
    alone = campaign_stats(report((KNEE,), ()), 1)
    assert alone is not None and alone.joint == "knee" and alone.energy.mean == 2.2
    assert campaign_stats(several, 2) is None  # no such configuration


def test_cycles_whose_trials_do_not_match_them_are_pooled_as_one_trial() -> None:
    for trials in ([1.0, 2.0], [1.0, 2.0, 3.0, 4.0]):  # one too few, one too many
        mismatched = dataclasses.replace(KNEE, energy_cycle_trial=np.asarray(trials))
        (row,) = headline_stats(report((mismatched,), ()), 1)
        assert row.energy.n == 1 and math.isclose(row.energy.mean, 2.2)
