"""Trajectory functions (Eq 4-7, 24-25, the calibration step) and trajectory files (CSV and .mat)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.io import savemat

from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.trajectories import (
    calibration_step_deg,
    calibration_step_peak_speed_deg_s,
    identification_deg,
    load_trajectory_file,
)


def test_identification_envelope_reaches_the_range_at_the_repetition_time() -> None:
    # Eq 4: exp(ln(max - min) * t / t_rep) = max - min at t = t_rep; cos^2 = 1 where pi*t/Period(t) = k*pi
    t_rep = 30.0
    t = np.linspace(0.0, t_rep - 1e-9, 300_001)
    y = identification_deg(t, 0.0, 110.0, t_rep, 8.0, 2.0)
    assert float(np.max(y)) == pytest.approx(110.0, rel=2e-3)
    assert float(np.min(y)) >= 0.0
    assert identification_deg(np.array([0.0]), 10.0, 110.0, t_rep, 8.0, 2.0)[0] == pytest.approx(
        11.0
    )  # e^0 = 1


def test_identification_repeats_join_without_jumps() -> None:
    """Every second repeat is the previous one played backwards, so each starts where the last ended (at
    rest): the motion repeats every two repetition times and has no jump (the thesis's 109 -> 1 deg)."""
    t = np.linspace(0.0, 29.0, 1000)
    a = identification_deg(t, 0.0, 110.0, 30.0, 8.0, 2.0)
    np.testing.assert_allclose(identification_deg(60.0 - t, 0.0, 110.0, 30.0, 8.0, 2.0), a, atol=1e-9)
    np.testing.assert_allclose(identification_deg(t + 60.0, 0.0, 110.0, 30.0, 8.0, 2.0), a, atol=1e-9)
    dt = 1e-3
    fine = identification_deg(np.arange(0.0, 90.0, dt), 0.0, 110.0, 30.0, 8.0, 2.0)
    assert np.max(np.abs(np.diff(fine))) < 0.2  # < 200 deg/s everywhere, junctions included
    for k in (30_000, 60_000):  # at a junction: extreme of the range, at rest
        assert fine[k] in (pytest.approx(110.0), pytest.approx(1.0))
        assert abs(fine[k + 1] - fine[k - 1]) / (2 * dt) < 0.01


def test_knee_identification_motion_stays_inside_the_joints_limits() -> None:
    """Eq 4-7 as the knee protocol declares it: peak speed and acceleration inside rig.safety."""
    from protocol_runner.protocol.loader import load_protocol

    from .test_plan import KNEE

    p = load_protocol(KNEE).protocol
    ident = p.trajectories["identification"]
    assert ident.kind == "identification" and isinstance(ident.range_deg, tuple)
    dt = 1e-3
    t = np.arange(0.0, ident.total_s, dt)
    y = identification_deg(
        t,
        ident.range_deg[0],
        ident.range_deg[1],
        ident.repetition_s,
        ident.initial_period_s,
        ident.final_period_s,
    )
    speed = np.diff(y) / dt
    accel = np.diff(speed) / dt
    assert np.max(np.abs(speed)) <= p.rig.safety.max_rate_deg_s
    assert np.max(np.abs(accel)) <= p.rig.safety.max_accel_deg_s2
    assert float(np.min(y)) >= ident.range_deg[0] - 1e-9 and float(np.max(y)) <= ident.range_deg[1] + 1e-9


def test_calibration_step_is_a_smooth_45_degree_move() -> None:
    t = np.arange(0.0, 5.6, 0.001)
    y = calibration_step_deg(t, 20.0, 45.0, settle_s=1.0, ramp_s=0.6)
    assert y[0] == 20.0 and y[-1] == pytest.approx(65.0)
    assert np.all(y[t < 1.0] == 20.0) and np.all(np.diff(y) >= 0)
    speed = float(np.max(np.abs(np.diff(y) / np.diff(t))))
    assert speed == pytest.approx(calibration_step_peak_speed_deg_s(45.0, 0.6), rel=1e-3)
    assert speed == pytest.approx(math.pi / 2 * 45.0 / 0.6, rel=1e-3)


def test_mat_trajectory_file_is_read(tmp_path: Path) -> None:
    t = np.arange(0.0, 10.0, 0.01)
    angle = 50.0 + 30.0 * np.sin(t)
    savemat(tmp_path / "subject.mat", {"time_s": t, "angle_deg": angle})
    traj = load_trajectory_file(tmp_path / "subject.mat")
    np.testing.assert_allclose(traj.angle_deg, angle)
    assert traj.duration_s == pytest.approx(9.99)
    np.testing.assert_allclose(traj.at(np.array([0.0, 5.0])), [50.0, 50.0 + 30.0 * np.sin(5.0)], atol=1e-9)


def test_mat_file_without_the_variables_is_refused(tmp_path: Path) -> None:
    savemat(tmp_path / "bad.mat", {"t": np.arange(3.0), "knee": np.arange(3.0)})
    with pytest.raises(InvalidInput, match="angle_deg"):
        load_trajectory_file(tmp_path / "bad.mat")


def test_csv_with_a_bad_row_names_the_line(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("# synthetic\ntime_s,angle_deg\n0,10\n0.01,eleven\n")
    with pytest.raises(InvalidInput, match=r"t\.csv:4:"):
        load_trajectory_file(path)


def test_time_must_increase(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text("time_s,angle_deg\n0,10\n0.02,11\n0.01,12\n")
    with pytest.raises(InvalidInput, match="increase strictly"):
        load_trajectory_file(path)


def test_shipped_synthetic_trajectories_say_what_they_are() -> None:
    folder = Path(__file__).resolve().parents[2] / "protocols" / "trajectories"
    files = sorted(folder.glob("subject_*_synthetic.csv"))
    assert len(files) == 3
    for f in files:
        traj = load_trajectory_file(f)
        assert "SYNTHETIC" in traj.header and "NOT human data" in traj.header
        assert traj.angle_deg.min() >= 0.0 and traj.angle_deg.max() <= 110.0  # inside R-E


def test_a_file_with_one_column_per_joint_gives_each_joint_its_own(tmp_path: Path) -> None:
    t = np.arange(0.0, 2.0, 0.01)
    hip, ankle = 10.0 + t, -5.0 - t
    savemat(tmp_path / "walk.mat", {"time_s": t, "hip_flexion": hip, "ankle_flexion_deg": ankle})
    np.testing.assert_allclose(load_trajectory_file(tmp_path / "walk.mat", "hip_flexion").angle_deg, hip)
    got = load_trajectory_file(tmp_path / "walk.mat", "ankle_flexion")
    np.testing.assert_allclose(got.angle_deg, ankle)
    assert got.column == "ankle_flexion_deg"
    with pytest.raises(InvalidInput, match="needs variables `time_s` and `knee_flexion`"):
        load_trajectory_file(tmp_path / "walk.mat", "knee_flexion")


def test_a_mat_file_declaring_too_many_elements_is_refused_before_it_is_loaded(tmp_path, monkeypatch) -> None:
    """A few hundred kB of compressed zeros can declare gigabytes: the declared sizes are read first."""
    import numpy as np
    import pytest
    import scipy.io

    from protocol_runner.errors import InvalidInput
    from protocol_runner.protocol import trajectories

    monkeypatch.setattr(trajectories, "MAX_MAT_ELEMENTS", 1000)
    path = tmp_path / "big.mat"
    scipy.io.savemat(path, {"time_s": np.arange(600) * 0.01, "angle_deg": np.zeros(600)}, do_compression=True)
    monkeypatch.setattr(
        scipy.io, "loadmat", lambda *a, **k: pytest.fail("loaded before its size was checked")
    )
    with pytest.raises(
        InvalidInput, match=r"big\.mat: its variables hold 1,200 elements, more than the 1,000"
    ):
        trajectories._load_mat(path, ("angle_deg",))
