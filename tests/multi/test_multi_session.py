"""A multi-joint session end to end (dry run of protocols/leg_phase2.yaml, one configuration): the archive
layout (one group per joint under a shared time base), processing per joint with the leg's total, the
calibration check per joint, and a resume inside the set giving bit-identical data."""

from __future__ import annotations

import errno
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive import units as units_module
from protocol_runner.archive.diskfull import DiskFull
from protocol_runner.commands import resume, run

from ..session.conftest import assert_same_data

REPO = Path(__file__).resolve().parents[2]
LEG = str(REPO / "protocols" / "leg_phase2.yaml")
JOINTS = ["hip_flexion", "knee_flexion", "ankle_flexion"]


def _run(session: Path) -> int:
    return run(LEG, dry_run=True, session=session, seed=11, yes=True, only=[2], realtime=False, quiet=True)


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> Path:
    session = tmp_path_factory.mktemp("leg") / "ref"
    assert _run(session) == 0
    return session / "archive.h5"


def test_a_trial_holds_one_group_per_joint_on_a_shared_time_base(reference: Path) -> None:
    with h5py.File(reference, "r") as f:
        trial = f["configurations/config_02/trials/1/brace_on"]
        assert list(trial.attrs["joints"]) == JOINTS
        t = trial["time_s"][:]
        for joint in JOINTS:
            g = trial[f"joints/{joint}"]
            assert np.array_equal(g["time_s"][:], t)
            assert g["angle_deg"].shape == t.shape and g["torque_nm"].shape == t.shape
            assert g["command_deg"].shape == trial["command_time_s"].shape
        # each joint followed its own column of the gait file (ranges of the SYNTHETIC file's header)
        knee = trial["joints/knee_flexion/angle_deg"][:]
        hip = trial["joints/hip_flexion/angle_deg"][:]
        assert 55 < knee.max() < 75 and 25 < hip.max() < 40
        # the brace-off twin follows each joint's brace-on output, its input scaled joint by joint (Eq 8)
        # in runs of every joint together: one run is kept for all, and in it each joint's cycle range
        # matches its brace-on cycle range within the protocol's tolerance (0.1 deg), or is flagged
        off = f["configurations/config_02/trials/1/brace_off"]
        scaling = [off[f"joints/{joint}/scaling"] for joint in JOINTS]
        (kept,) = {int(s.attrs["kept_iteration"]) for s in scaling}
        for s in scaling:
            error = float(s["range_error_deg"][kept - 1])
            assert bool(s.attrs["converged"]) == (error <= 0.1)
            output, target = s["output_range_deg"][kept - 1], s.attrs["target_range_deg"]
            assert np.max(np.abs(output - target)) == pytest.approx(error)
        assert sum(bool(s.attrs["converged"]) for s in scaling) >= 2


def test_processing_per_joint_and_the_legs_total(reference: Path) -> None:
    with h5py.File(reference, "r") as f:
        cfg = f["configurations/config_02"]
        per_joint = {j: cfg[f"joints/{j}/energy_loss_j"][:] for j in JOINTS}
        # the hip carries nothing: its brace-on and brace-off torques agree and it loses ~no energy; the
        # knee's brake (3.75 N*m) and hinge lose most (about 4*T*A per cycle, A ~ 0.45 rad)
        assert abs(per_joint["hip_flexion"].mean()) < 0.3
        assert 4.0 < per_joint["knee_flexion"].mean() < 12.0
        assert per_joint["knee_flexion"].mean() > per_joint["ankle_flexion"].mean() > 0.1
        total = cfg["total_energy_loss_j"][:]
        trials = cfg["total_energy_cycle_trial"][:]
        # the total of cycle k of trial n is the sum over joints of their cycle k of trial n
        for n in set(trials.tolist()):
            k = int(np.sum(trials == n))
            parts = [per_joint[j][cfg[f"joints/{j}/energy_cycle_trial"][:] == n][:k] for j in JOINTS]
            assert total[trials == n] == pytest.approx(np.sum(parts, axis=0))
        assert cfg["joints/knee_flexion/trials/1/processed/brace_torque_nm"].size > 0
        # Bouc-Wen per joint that carries elements (knee, ankle); the bare hip is not fitted
        assert (
            "fits/bouc_wen" in cfg["joints/knee_flexion"] and "fits/bouc_wen" in cfg["joints/ankle_flexion"]
        )
        assert "fits" not in cfg["joints/hip_flexion"]
        assert cfg["joints/knee_flexion/fits/bouc_wen"].attrs["r2"] > 0.5


def test_calibration_is_checked_per_joint(reference: Path) -> None:
    with h5py.File(reference, "r") as f:
        check = f["calibration/leg/before"]
        assert check.attrs["verdict"] == "pass"
        for joint, target in zip(JOINTS, (40.0, 65.0, 10.0), strict=True):
            g = check[f"joints/{joint}"]
            assert g.attrs["settled_deg"] == pytest.approx(target, abs=3.0)  # its own step, its own range
            assert 0.1 < g.attrs["time_constant_s"] < 0.35


def test_a_failing_joint_is_named(tmp_path: Path) -> None:
    from protocol_runner.cli import main

    text = Path(LEG).read_text(encoding="utf-8")
    # the ankle's step must settle within 0.001 deg of the target: impossible with the sensor's noise
    bad = text.replace("max_settle_error_deg: 3.0", "max_settle_error_deg: 0.001")
    import shutil

    shutil.copytree(REPO / "protocols", tmp_path / "p")
    (tmp_path / "p" / "strict.yaml").write_text(bad, encoding="utf-8")
    session = tmp_path / "s"
    assert (
        main(
            [
                str(tmp_path / "p" / "strict.yaml"),
                "--dry-run",
                "--only",
                "2",
                "--session",
                str(session),
            ]
        )
        == 4
    )
    with h5py.File(session / "archive.h5", "r") as f:
        msg = f["calibration/leg/before"].attrs["message"]
        assert "joint hip_flexion: settle error" in msg and "joint ankle_flexion: settle error" in msg


def test_resume_inside_the_multi_joint_set_is_bit_identical(
    tmp_path: Path, reference: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "resumed"
    real = units_module._fsync_file
    calls = {"n": 0}

    def failing_fsync(path: Path) -> None:
        calls["n"] += 1
        if calls["n"] == 5:  # the disk fills while the brace-on trials of the set are being written
            raise OSError(errno.ENOSPC, "No space left on device")
        real(path)

    monkeypatch.setattr(units_module, "_fsync_file", failing_fsync)
    with pytest.raises(DiskFull):
        _run(session)
    monkeypatch.setattr(units_module, "_fsync_file", real)
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert_same_data(reference, session / "archive.h5")
    with h5py.File(session / "archive.h5", "r") as f:
        assert "joints" in f["calibration/leg/resume_1"]  # the extra check on resuming: per joint too


def test_reprocess_of_a_multi_joint_archive_reproduces_the_sessions_numbers(
    reference: Path, tmp_path: Path
) -> None:
    from protocol_runner.archive.reprocess import reprocess_archive

    out = reprocess_archive(reference, output=tmp_path / "re.h5")
    with h5py.File(reference, "r") as a, h5py.File(out, "r") as b:
        cfg_a, cfg_b = a["configurations/config_02"], b["configurations/config_02"]
        assert np.array_equal(cfg_a["total_energy_loss_j"][:], cfg_b["total_energy_loss_j"][:])
        for joint in JOINTS:
            assert np.array_equal(
                cfg_a[f"joints/{joint}/energy_loss_j"][:], cfg_b[f"joints/{joint}/energy_loss_j"][:]
            )
            path = f"joints/{joint}/trials/2/processed/brace_torque_nm"
            assert np.array_equal(cfg_a[path][:], cfg_b[path][:])
        for joint in ("knee_flexion", "ankle_flexion"):
            fa, fb = cfg_a[f"joints/{joint}/fits/bouc_wen"], cfg_b[f"joints/{joint}/fits/bouc_wen"]
            assert fa.attrs["rmse_nm"] == pytest.approx(fb.attrs["rmse_nm"], rel=1e-9)  # as tests/archive


def test_sigint_during_a_multi_joint_trial_exits_130_and_resume_is_bit_identical(
    tmp_path: Path, reference: Path
) -> None:
    import signal

    from ..session.conftest import cli
    from ..session.test_fault_injection import journal_units, wait_for_units

    session = tmp_path / "sigint"
    proc = cli(
        LEG,
        "--dry-run",
        "--only",
        "2",
        "--seed",
        "11",
        "--session",
        str(session),
        log=tmp_path / "e",
    )
    assert wait_for_units(proc, session, 3)  # inside the set: the brace-on trials are running
    proc.send_signal(signal.SIGINT)
    proc.wait(timeout=120)
    assert proc.returncode == 130, proc.stderr()
    assert "Traceback" not in proc.stderr()
    done = journal_units(session)
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert journal_units(session) > done
    assert_same_data(reference, session / "archive.h5")
