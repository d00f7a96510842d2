"""An archive of one joint written before every group was keyed by joint (its trial, calibration,
configuration and comparison groups hold that joint's datasets themselves) is still read: it verifies, and
`--report --reprocess` reads it as its one joint's and writes the same numbers keyed by joint.

The former layout is made from a fresh archive by `former_layout.to_former_layout`."""

from __future__ import annotations

import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner import commands
from protocol_runner.archive.reprocess import reprocess_archive
from protocol_runner.archive.verify import verify_path

from .former_layout import JOINT, TOTALS, to_former_layout


@pytest.fixture(scope="module")
def former(reference_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("former") / "archive.h5"
    shutil.copyfile(reference_archive, path)
    to_former_layout(path)
    with h5py.File(path, "r") as f:  # the layout written before: no group is keyed by joint
        found: list[str] = []
        f.visit(lambda name: found.append(name) if name.endswith("/joints") else None)
        assert not found and "energy_loss_j" in f["configurations/config_12"]
    return path


def test_an_archive_of_the_former_layout_verifies(former: Path) -> None:
    verdict = verify_path(former)
    assert not verdict.problems and "every checksum matches" in verdict.lines[0]


def test_reprocessing_the_former_layout_gives_the_sessions_numbers_keyed_by_joint(
    former: Path, reference_archive: Path, tmp_path: Path
) -> None:
    out = reprocess_archive(former, output=tmp_path / "re.h5")
    with h5py.File(reference_archive, "r") as ref, h5py.File(out, "r") as new:
        a, b = ref["configurations/config_12"], new["configurations/config_12"]
        assert "energy_loss_j" not in b and list(b.attrs["joints"]) == [JOINT]
        for name in (
            f"joints/{JOINT}/energy_loss_j",
            f"joints/{JOINT}/trials/1/processed/brace_torque_nm",
            f"joints/{JOINT}/fits/bouc_wen/model_torque_nm",
            *TOTALS,
        ):
            assert np.array_equal(a[name][()], b[name][()]), name
        assert np.array_equal(b["total_energy_loss_j"][()], b[f"joints/{JOINT}/energy_loss_j"][()])
        assert b[f"joints/{JOINT}/fits/bouc_wen"].attrs["A"] == a[f"joints/{JOINT}/fits/bouc_wen"].attrs["A"]
        for name, comp in ref.get("comparisons", {}).items():
            for key in ("energy_mean_j", "energy_cycles"):
                assert np.array_equal(
                    comp[f"joints/{JOINT}"].attrs[key], new[f"comparisons/{name}/joints/{JOINT}"].attrs[key]
                )
    assert not verify_path(out).problems


def test_report_reprocess_of_the_former_layout_finishes(former: Path, tmp_path: Path) -> None:
    copy = tmp_path / "archive.h5"
    shutil.copyfile(former, copy)
    assert (
        commands.report(copy, output=tmp_path / "r.html", reprocess=True, protocol_file=None, export_mat=None)
        == 0
    )
