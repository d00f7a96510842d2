"""`--export-mat` of an archive of several joints: each joint's data in `joints.<joint>` of its
configuration's file and of session.mat's summary, what the joints share at the top (docs/matlab.md)."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest
from scipy.io import loadmat

from protocol_runner.archive.export import export_mat

from .conftest import LEG_JOINTS

OCTAVE = shutil.which("octave-cli") or shutil.which("octave")


@pytest.fixture(scope="module")
def exported(leg_archive: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("leg_mat")
    export_mat(leg_archive, folder)
    return folder


def _load(path: Path) -> dict[str, Any]:
    return loadmat(path, squeeze_me=True, struct_as_record=False, chars_as_strings=True)


def test_each_joint_has_its_own_trials_energies_fits_and_calibration(
    leg_archive: Path, exported: Path
) -> None:
    c = _load(exported / "config_03.mat")
    assert list(c["joints"]._fieldnames) == list(LEG_JOINTS)  # channel order
    with h5py.File(leg_archive, "r") as f:
        cfg = f["configurations/config_03"]
        for joint in LEG_JOINTS:
            j = getattr(c["joints"], joint)
            part = cfg[f"joints/{joint}"]
            assert np.array_equal(j.energy_loss_j, part["energy_loss_j"][()])
            assert j.energy_mean_j == part["energy_loss_j"].attrs["mean_j"]
            # trial 2: that joint's processed loop and its own recording, not another joint's
            assert np.array_equal(j.trial_2.brace_torque_nm, part["trials/2/processed/brace_torque_nm"][()])
            own = cfg[f"trials/2/brace_on/joints/{joint}"]
            assert j.trial_2.brace_on.joint == joint
            assert np.array_equal(j.trial_2.brace_on.angle_deg, own["angle_deg"][()])
            assert j.calibration.before.joint == joint
            assert (
                j.calibration.before.settled_deg
                == f[f"calibration/leg/before/joints/{joint}"].attrs["settled_deg"]
            )
            assert hasattr(j, "bouc_wen") == (joint != "hip_flexion")  # the bare hip carries nothing to fit
        # what the joints share: the trial's one time base and the total energy per cycle
        assert np.array_equal(c["trial_2"].brace_on.time_s, cfg["trials/2/brace_on/time_s"][()])
        assert list(c["trial_2"].brace_on.joints) == list(LEG_JOINTS)  # the attribute: no joint's data
        total = cfg["total_energy_loss_j"][()]
        assert np.array_equal(c["total_energy_loss_j"], total)
        assert c["total_energy_mean_j"] == pytest.approx(total.mean(), rel=1e-12)
    assert c["units"].energy_loss_j == "J" and c["units"].total_energy_mean_j == "J"


def test_the_session_summary_gives_each_joints_energy(leg_archive: Path, exported: Path) -> None:
    s = _load(exported / "session.mat")
    summary = s["configurations"].config_01
    with h5py.File(leg_archive, "r") as f:
        for joint in LEG_JOINTS:
            loss = f[f"configurations/config_01/joints/{joint}/energy_loss_j"]
            got = getattr(summary.joints, joint)
            assert (got.energy_mean_j, got.energy_cycles) == (loss.attrs["mean_j"], loss.shape[0])
    assert summary.file == "config_01.mat"


@pytest.mark.skipif(OCTAVE is None, reason="GNU Octave (octave-cli) is not installed")
def test_octave_reads_a_value_of_every_joint(leg_archive: Path, exported: Path) -> None:
    assert OCTAVE is not None
    script = exported / "joints.m"
    script.write_text(
        "c = load('config_03.mat');\n"
        "names = fieldnames(c.joints);\n"
        "for k = 1:numel(names)\n"
        "  j = c.joints.(names{k});\n"
        "  printf('%s %.17g %d\\n', names{k}, j.energy_mean_j, numel(j.trial_1.angle_deg));\n"
        "end\n"
    )
    options = ["--norc", "--no-history"] + ([] if OCTAVE.endswith("-cli") else ["--no-gui"])
    done = subprocess.run(
        [OCTAVE, *options, script.name], cwd=exported, capture_output=True, text=True, timeout=300
    )
    assert done.returncode == 0, done.stderr[-2000:]
    lines = [line.split() for line in done.stdout.splitlines()]
    assert [line[0] for line in lines] == list(LEG_JOINTS)
    with h5py.File(leg_archive, "r") as f:
        for joint, mean, n in lines:
            part = f[f"configurations/config_03/joints/{joint}"]
            assert float(mean) == part["energy_loss_j"].attrs["mean_j"]
            assert int(n) == part["trials/1/processed/angle_deg"].shape[0]
