"""`--compare A B` per joint: each matched configuration compared joint by joint and, for several joints,
for all of them together; an archive of one joint written before groups were keyed by joint pairs with
one written after (docs/report.md "Session comparison")."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest
from scipy import stats

from protocol_runner.report.compare import TOTAL, compare_archives, render_comparison

from ..archive.former_layout import to_former_layout
from .conftest import LEG_JOINTS


def test_each_joint_and_the_total_is_compared(leg_archive: Path, tmp_path: Path) -> None:
    other = tmp_path / "b.h5"
    shutil.copyfile(leg_archive, other)
    result = compare_archives(leg_archive, other)
    assert [(p.a.key, p.joint) for p in result.pairs] == [
        (k, j) for k in (1, 3) for j in (*LEG_JOINTS, TOTAL)
    ]
    with h5py.File(leg_archive, "r") as f:
        for p in result.pairs:
            assert p.energy.difference == 0.0 and not p.significant  # the same data on both sides
            assert p.a.joint == p.b.joint == (LEG_JOINTS[0] if p.total else p.joint)
            cfg = f[f"configurations/config_{p.a.key:02d}"]
            own = cfg if p.total else cfg[f"joints/{p.joint}"]
            prefix = "total_" if p.total else ""
            loss, trial = own[f"{prefix}energy_loss_j"][()], own[f"{prefix}energy_cycle_trial"][()]
            means = np.array([loss[trial == n].mean() for n in np.unique(trial)])
            # the interval is that joint's (or the total's) own: the spread of its trial means, both sides
            half = stats.t.ppf(0.975, 2 * (means.size - 1)) * np.sqrt(2 * means.var(ddof=1) / means.size)
            assert p.energy.high == pytest.approx(half, rel=1e-9)
    table = result.table().splitlines()
    assert table[0].split()[:3] == ["A", "B", "joint"]
    total_line = next(line for line in table if " total " in line)
    assert total_line.split()[7:] == ["—", "—", "—", "none"]  # a range has no total
    assert table[-1].startswith(
        "2 matched configurations (8 comparisons: per joint, and all joints together)"
    )
    html = render_comparison(result, tmp_path / "c.html").read_text(encoding="utf-8")
    assert re.findall(r'data-joint="(\w+)"', html) == [p.joint for p in result.pairs]
    assert html.count("<figure") == 6  # a loop overlay per joint, none for the totals


def test_a_single_joint_archive_pairs_with_its_joint_keyed_twin(
    reference_archive: Path, tmp_path: Path
) -> None:
    """The same data, one archive keyed by joint and one without `joints/` (the layout written before every
    group was keyed by joint): every number of the comparison is the same as the archive's with itself."""
    former = tmp_path / "former.h5"
    shutil.copyfile(reference_archive, former)
    to_former_layout(former)
    itself = compare_archives(reference_archive, reference_archive)
    across = compare_archives(former, reference_archive)
    assert (
        [(p.a.key, p.joint) for p in across.pairs]
        == [(p.a.key, p.joint) for p in itself.pairs]
        == [(12, "knee_flexion")]
    )
    for a, b in zip(itself.pairs, across.pairs, strict=True):
        assert (b.energy.difference, b.range.difference) == (0.0, 0.0)
        assert (b.energy.low, b.energy.high) == pytest.approx((a.energy.low, a.energy.high), rel=1e-12)
        assert b.a.energy_loss_j.tolist() == b.b.energy_loss_j.tolist()
    assert across.table().splitlines()[-1] == itself.table().splitlines()[-1]
