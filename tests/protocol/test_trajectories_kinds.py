"""Every trajectory kind built from its spec, sampled, and checked against the joint's limits.

Facts: the sinusoid's peak speed is `speed_deg_s` (Eq 25) and its period follows; the triangle moves at
constant speed between corners whose acceleration is the corner limit, reaching the range's ends; the ramped
step's peak speed is pi/2*step/ramp; a file is reproduced at the output rate; a hold is constant; every
kind lasts its JSON duration_s; a trajectory over a limit is refused naming its field.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from pydantic import TypeAdapter

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.safety import SafetyLimits
from protocol_runner.hardware.stream import build_stream, check_stream
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.protocol.stream_check import trajectory_limit_problems
from protocol_runner.protocol.trajectories import (
    calibration_step_peak_accel_deg_s2,
    calibration_step_peak_speed_deg_s,
    sinusoid_deg,
)
from protocol_runner.protocol.trajectory_record import Trajectory
from protocol_runner.protocol.trajectory_specs import (
    Quantity,
    TrajectorySpec,
    build_trajectory,
    trajectory_bindings,
)

SPEC: TypeAdapter[TrajectorySpec] = TypeAdapter(TrajectorySpec)
LIMITS = SafetyLimits(
    range_deg=(-45.0, 30.0),
    max_rate_deg_s=100.0,
    max_accel_deg_s2=1500.0,
    park_angle_deg=0.0,
    park_rate_deg_s=20.0,
)
FINE_HZ = 10_000.0  # fine sampling to measure speeds and accelerations
REPO = Path(__file__).resolve().parents[2]


def build(doc: dict[str, object], values: dict[str, Quantity] | None = None, base: Path = REPO) -> Trajectory:
    return build_trajectory("t", SPEC.validate_python(doc), values or {}, base, limits=LIMITS)


def speed_accel(samples: np.ndarray, rate_hz: float) -> tuple[np.ndarray, np.ndarray]:
    v = np.diff(samples) * rate_hz
    return v, np.diff(v) * rate_hz


def test_sinusoid_peak_speed_is_speed_deg_s_and_the_period_follows_eq_25() -> None:
    traj = build(
        {"kind": "sinusoid", "range_deg": "rom.range_deg", "speed_deg_s": 40, "periods": 3},
        {"range_deg": (-30.0, 20.0)},
    )
    amplitude = 25.0
    assert traj.period_s == pytest.approx(2 * math.pi * amplitude / 40.0)  # Eq 25: p = 2 pi A / v
    assert traj.duration_s == pytest.approx(3 * traj.period_s)
    js = traj.to_json()
    assert js["profile"] == "sinusoid" and js["name"] == "t"
    assert (js["mean_deg"], js["amplitude_deg"], js["range_deg"], js["speed_deg_s"]) == (
        -5.0,
        25.0,
        [-30.0, 20.0],
        40.0,
    )
    y = sample_trajectory(traj, FINE_HZ, REPO)
    v, a = speed_accel(y, FINE_HZ)
    assert float(np.max(np.abs(v))) == pytest.approx(40.0, rel=1e-4)
    assert float(np.max(np.abs(a))) == pytest.approx(40.0**2 / amplitude, rel=1e-3)  # A (2 pi/p)^2
    assert float(y.min()) == pytest.approx(-30.0, abs=1e-6) and float(y.max()) == pytest.approx(
        20.0, abs=1e-6
    )
    # one period later the motion repeats (Eq 24)
    t = np.arange(y.size) / FINE_HZ
    np.testing.assert_allclose(sinusoid_deg(t + traj.period_s, -5.0, 25.0, traj.period_s), y, atol=1e-9)


@pytest.mark.parametrize("corner", [None, 600.0])
def test_triangle_constant_speed_between_corners_at_the_corner_acceleration(corner: float | None) -> None:
    doc: dict[str, object] = {"kind": "triangle", "range_deg": [-40, 25], "speed_deg_s": 50, "cycles": 2}
    if corner is not None:
        doc["corner_accel_deg_s2"] = corner
    traj = build(doc)
    accel = corner if corner is not None else LIMITS.max_accel_deg_s2  # default: the joint's limit
    assert traj.param("corner_accel_deg_s2") == accel
    assert traj.duration_s == pytest.approx(2 * (2 * 65.0 / 50.0 + 2 * 50.0 / accel))
    y = sample_trajectory(traj, FINE_HZ, REPO)
    v, a = speed_accel(y, FINE_HZ)
    # the ends reach the range exactly, start and end at rest at the low end
    assert float(y.min()) == pytest.approx(-40.0, abs=1e-9) and float(y.max()) == pytest.approx(
        25.0, abs=1e-6
    )
    assert y[0] == -40.0 and abs(v[0]) < 1.0 and y[-1] == pytest.approx(-40.0, abs=1e-3)
    # constant speed away from the corners (which lie within speed^2/(2 accel) of the ends)
    margin = 50.0**2 / (2 * accel)
    inside = (y[:-1] > -40.0 + margin + 0.01) & (y[:-1] < 25.0 - margin - 0.01)
    np.testing.assert_allclose(np.abs(v[inside]), 50.0, rtol=1e-9)
    assert float(np.max(np.abs(v))) == pytest.approx(50.0, rel=1e-9)
    # the peak acceleration is the corner limit, and nothing exceeds it
    assert float(np.max(np.abs(a))) == pytest.approx(accel, rel=1e-3)
    assert float(np.max(np.abs(a))) <= accel * (1 + 1e-6)


def test_triangle_at_the_joints_acceleration_limit_passes_the_complete_stream_check() -> None:
    """Corners at exactly the acceleration limit, ends at exactly the range: the approach, the exit and a
    stop from any sample stay inside the envelope (hardware/stream.py)."""
    traj = build({"kind": "triangle", "range_deg": [-45, 30], "speed_deg_s": 100, "cycles": 1.5})
    assert trajectory_limit_problems(traj, LIMITS, 100.0, REPO) == []
    samples = sample_trajectory(traj, 100.0, REPO)
    check_stream(build_stream(samples, LIMITS, 100.0), LIMITS, where="stream")


def test_ramped_step_peak_speed_and_acceleration_match_their_closed_forms() -> None:
    traj = build(
        {"kind": "ramped_step", "from_deg": -20, "step_deg": 30, "ramp_s": 0.8, "hold_s": 2, "settle_s": 1}
    )
    assert traj.duration_s == pytest.approx(3.8) and traj.to_json()["hold_s"] == 2.0
    y = sample_trajectory(traj, FINE_HZ, REPO)
    v, a = speed_accel(y, FINE_HZ)
    assert float(np.max(v)) == pytest.approx(math.pi / 2 * 30.0 / 0.8, rel=1e-4)
    assert float(np.max(np.abs(a))) == pytest.approx(math.pi**2 / 2 * 30.0 / 0.8**2, rel=1e-2)
    assert calibration_step_peak_speed_deg_s(30.0, 0.8) == pytest.approx(float(np.max(v)), rel=1e-4)
    assert calibration_step_peak_accel_deg_s2(30.0, 0.8) == pytest.approx(float(np.max(np.abs(a))), rel=1e-2)
    assert y[0] == -20.0 and y[-1] == pytest.approx(10.0)
    assert np.all(y[: int(FINE_HZ)] == -20.0)  # the settle hold


def test_hold_is_constant() -> None:
    traj = build({"kind": "hold", "angle_deg": "stops.angle_deg", "duration_s": 2.5}, {"angle_deg": -12.5})
    y = sample_trajectory(traj, 100.0, REPO)
    assert y.size == 250 and np.all(y == -12.5)


def _write(path: Path, text: str) -> Path:
    path.write_text(text, encoding="utf-8")
    return path


def test_file_trajectory_reproduces_the_file_samples_at_the_output_rate(tmp_path: Path) -> None:
    t = np.arange(0, 501) / 100.0
    hip = 10.0 * np.sin(t)
    ankle = -5.0 + 20.0 * np.sin(0.7 * t)
    rows = "\n".join(f"{a:.2f},{b:.6f},{c:.6f}" for a, b, c in zip(t, hip, ankle, strict=True))
    _write(tmp_path / "walk.csv", f"# gait lab, subject 3, 2024\ntime_s,hip_flexion,ankle_flexion\n{rows}\n")
    spec = SPEC.validate_python({"kind": "file", "file": "walk.csv"})
    traj = build_trajectory("walk", spec, {}, tmp_path, joint="ankle_flexion")
    js = traj.to_json()
    assert js["source"] == "walk.csv" and js["column"] == "ankle_flexion"
    assert js["origin"] == "gait lab, subject 3, 2024" and js["duration_s"] == pytest.approx(5.0)
    y = sample_trajectory(traj, 100.0, tmp_path)
    np.testing.assert_allclose(y, np.round(ankle, 6)[: y.size], atol=1e-9)
    # at twice the file's rate, the samples between are the linear interpolation
    y2 = sample_trajectory(traj, 200.0, tmp_path)
    np.testing.assert_allclose(y2[1:-1:2], (y[:-1] + y[1:]) / 2, atol=1e-9)


def test_file_needs_its_origin_and_its_joints_column(tmp_path: Path) -> None:
    _write(tmp_path / "bare.csv", "time_s,angle_deg\n0,1\n1,2\n")
    spec = SPEC.validate_python({"kind": "file", "file": "bare.csv"})
    with pytest.raises(InvalidInput, match="state where the motion comes from"):
        build_trajectory("bare", spec, {}, tmp_path)
    stated = SPEC.validate_python({"kind": "file", "file": "bare.csv", "origin": "hand-made test ramp"})
    assert build_trajectory("bare", stated, {}, tmp_path).to_json()["origin"] == "hand-made test ramp"
    _write(tmp_path / "two.csv", "# lab\ntime_s,hip_flexion,ankle_flexion\n0,1,2\n1,2,3\n")
    two = SPEC.validate_python({"kind": "file", "file": "two.csv"})
    with pytest.raises(
        InvalidInput, match=r"trajectory 'two': .*two\.csv:2: .*`knee_flexion` or `angle_deg`"
    ):
        build_trajectory("two", two, {}, tmp_path, joint="knee_flexion")
    outside = SPEC.validate_python({"kind": "file", "file": "../elsewhere.csv"})
    with pytest.raises(InvalidInput, match=r"trajectory 'x': file: .*outside the protocol's folder"):
        build_trajectory("x", outside, {}, tmp_path)


def test_the_shipped_human_files_load_as_file_trajectories() -> None:
    base = REPO / "protocols"
    for name in ("B", "C", "E"):
        spec = SPEC.validate_python({"kind": "file", "file": f"trajectories/subject_{name}_synthetic.csv"})
        traj = build_trajectory(f"subject_{name}", spec, {}, base, joint="knee_flexion")
        assert traj.param("column") == "angle_deg" and "SYNTHETIC" in str(traj.param("origin"))
        y = sample_trajectory(traj, 100.0, base)
        assert y.size == round(traj.duration_s * 100.0)


KINDS: list[dict[str, object]] = [
    {"kind": "sinusoid", "range_deg": [-40, 20], "speed_deg_s": 60, "periods": 2},
    {"kind": "triangle", "range_deg": [-40, 20], "speed_deg_s": 60, "cycles": 1.5},
    {"kind": "file", "file": "trajectories/subject_B_synthetic.csv"},
    {
        "kind": "identification",
        "range_deg": [-44, 29],
        "total_s": 40,
        "repetition_s": 20,
        "initial_period_s": 8,
        "final_period_s": 3.2,
    },
    {"kind": "ramped_step", "from_deg": -20, "step_deg": 30, "ramp_s": 0.6, "hold_s": 4, "settle_s": 1},
    {"kind": "hold", "angle_deg": 5, "duration_s": 3},
]


@pytest.mark.parametrize("doc", KINDS, ids=[str(d["kind"]) for d in KINDS])
def test_each_kind_lasts_its_json_duration(doc: dict[str, object]) -> None:
    base = REPO / "protocols"
    traj = build(doc, base=base)
    js = traj.to_json()
    assert js["profile"] == doc["kind"] and js["name"] == "t"
    for rate in (100.0, 250.0):
        y = sample_trajectory(traj, rate, base)
        assert y.size == pytest.approx(js["duration_s"] * rate, abs=1.0)
        assert np.all(np.isfinite(y))


def test_file_kind_checked_against_the_joint_envelope_only_when_outside() -> None:
    """The knee stand-in files (0-110 deg) are outside this ankle-like joint's range: refused naming `file`."""
    base = REPO / "protocols"
    traj = build({"kind": "file", "file": "trajectories/subject_B_synthetic.csv"}, base=base)
    problems = trajectory_limit_problems(traj, LIMITS, 100.0, base)
    assert [f for f, _ in problems] == ["file"]
    assert "joint angle" in problems[0][1] and "-45 to 30 deg" in problems[0][1]
    wide = SafetyLimits((0.0, 130.0), 120.0, 2000.0, 45.0, 20.0)
    assert trajectory_limit_problems(traj, wide, 100.0, base) == []


@pytest.mark.parametrize(
    ("doc", "values", "field", "words"),
    [
        (
            {"kind": "sinusoid", "range_deg": "rom.range_deg", "speed_deg_s": 60, "periods": 2},
            {"range_deg": (-50.0, 20.0)},
            "range_deg",
            r"range_deg \(bound to rom.range_deg\): \[-50, 20\] deg is outside the joint's range \[-45, 30\]",
        ),
        (
            {"kind": "sinusoid", "range_deg": [-40, 20], "speed_deg_s": "speed.speed_deg_s", "periods": 2},
            {"speed_deg_s": 120.0},
            "speed_deg_s",
            r"peak speed \(Eq 25\) 120 deg/s is over the joint's rate limit max_rate_deg_s = 100",
        ),
        (
            {"kind": "sinusoid", "range_deg": [-5, 5], "speed_deg_s": 90, "periods": 2},
            {},
            "speed_deg_s",
            r"peak acceleration speed²/amplitude 1620 deg/s² is over .* max_accel_deg_s2 = 1500",
        ),
        (
            {"kind": "triangle", "range_deg": [-40, 20], "speed_deg_s": 110, "cycles": 1},
            {},
            "speed_deg_s",
            "constant speed 110 deg/s is over the joint's rate limit",
        ),
        (
            {
                "kind": "triangle",
                "range_deg": [-40, 20],
                "speed_deg_s": 60,
                "cycles": 1,
                "corner_accel_deg_s2": 2000,
            },
            {},
            "corner_accel_deg_s2",
            "corners' acceleration 2000 deg/s² is over the joint's acceleration limit",
        ),
        (
            {
                "kind": "ramped_step",
                "from_deg": -20,
                "step_deg": 60,
                "ramp_s": 0.6,
                "hold_s": 1,
                "settle_s": 1,
            },
            {},
            "step_deg",
            r"from_deg \+ step_deg = 40 is outside",
        ),
        (
            {
                "kind": "ramped_step",
                "from_deg": -20,
                "step_deg": 30,
                "ramp_s": 0.3,
                "hold_s": 1,
                "settle_s": 1,
            },
            {},
            "ramp_s",
            r"peak speed pi/2\*step/ramp 157.1 deg/s is over",
        ),
        (
            {"kind": "ramped_step", "from_deg": -20, "step_deg": 30, "ramp_s": 0, "hold_s": 1, "settle_s": 1},
            {},
            "ramp_s",
            "inf deg/s is over",
        ),
        (
            {"kind": "hold", "angle_deg": "stops.angle_deg", "duration_s": 1},
            {"angle_deg": 31.0},
            "angle_deg",
            r"angle_deg \(bound to stops.angle_deg\): 31 deg is outside",
        ),
        (
            {
                "kind": "identification",
                "range_deg": [-44, 29],
                "total_s": 40,
                "repetition_s": 20,
                "initial_period_s": 8,
                "final_period_s": 1.5,
            },
            {},
            "final_period_s",
            r"angular (rate|acceleration) reaches .* at t = .* the joint allows ±",
        ),
    ],
)
def test_trajectories_over_a_limit_are_refused_naming_the_field(
    doc: dict[str, object], values: dict[str, Quantity], field: str, words: str
) -> None:
    spec = SPEC.validate_python(doc)
    traj = build_trajectory("sine", spec, values, REPO, limits=LIMITS)
    problems = trajectory_limit_problems(traj, LIMITS, 100.0, REPO, trajectory_bindings(spec))
    assert problems, "the trajectory should have been refused"
    assert problems[0][0] == field
    assert problems[0][1].startswith(f"trajectory 'sine' ({doc['kind']}): {field}")
    assert any(re.search(words, m) for _, m in problems), problems


def test_every_kind_inside_the_limits_passes_both_checks() -> None:
    base = REPO / "protocols"
    wide = SafetyLimits((-45.0, 130.0), 120.0, 2000.0, 0.0, 20.0)
    for doc in KINDS:
        traj = build_trajectory("t", SPEC.validate_python(doc), {}, base, limits=wide)
        assert trajectory_limit_problems(traj, wide, 100.0, base) == [], doc["kind"]
        check_stream(
            build_stream(sample_trajectory(traj, 100.0, base), wide, 100.0), wide, where=str(doc["kind"])
        )


def test_a_triangle_too_fast_for_its_range_is_refused_naming_speed() -> None:
    with pytest.raises(
        InvalidInput, match=r"trajectory 't': speed_deg_s 100 deg/s cannot be reached.*20 deg"
    ):
        build(
            {
                "kind": "triangle",
                "range_deg": [0, 5],
                "speed_deg_s": 100,
                "corner_accel_deg_s2": 500,
                "cycles": 1,
            }
        )


def test_bound_fields_need_a_value_of_the_right_shape() -> None:
    doc = {"kind": "sinusoid", "range_deg": "rom.range_deg", "speed_deg_s": "speed.speed_deg_s", "periods": 1}
    with pytest.raises(InvalidInput, match=r"range_deg is bound to rom.range_deg but no value"):
        build(doc, {"speed_deg_s": 10.0})
    with pytest.raises(InvalidInput, match=r"speed_deg_s \(bound to speed.speed_deg_s\): expected a number"):
        build(doc, {"range_deg": (0.0, 10.0), "speed_deg_s": (1.0, 2.0)})
    with pytest.raises(InvalidInput, match=r"range_deg \(bound to rom.range_deg\): expected a range"):
        build(doc, {"range_deg": 10.0, "speed_deg_s": 10.0})
    with pytest.raises(
        InvalidInput, match=r"speed_deg_s \(bound to speed.speed_deg_s\): must be greater than 0"
    ):
        build(doc, {"range_deg": (0.0, 10.0), "speed_deg_s": 0.0})


def test_the_migrated_knee_protocol_commands_todays_samples() -> None:
    """knee_phase1 in schema_version 2 commands the samples the version-1 path did: each sinusoid is Eq 24
    with the range of its robot_rom level and the period of Eq 25 from its speed level (the Table 6
    periods), over 8 periods; the calibration step is the 20 -> 65 deg raised cosine over 0.6 s."""
    from protocol_runner.protocol.loader import load_protocol
    from protocol_runner.protocol.plan import expand
    from protocol_runner.protocol.plan_steps import CalibrationCheckStep, TrialStep
    from protocol_runner.protocol.trajectories import calibration_step_deg, sinusoid_deg

    from .test_plan import ROM_DEG, SPEED, TABLE_5

    loaded = load_protocol(REPO / "protocols" / "knee_phase1.yaml")
    plan = expand(loaded)
    rate = loaded.protocol.rig.output.rate_hz
    for step in plan.steps:
        if isinstance(step, TrialStep) and step.brace == "on" and step.trial == 1:
            _, _, robot, _, _, speed, _, profile = TABLE_5[step.configuration]
            if profile != "sinusoid":
                continue
            lo, hi = ROM_DEG[robot.replace("Rr", "R")]
            amplitude = (hi - lo) / 2.0
            period = 2.0 * np.pi * amplitude / SPEED[speed]
            t = np.arange(0.0, 8 * period, 1.0 / rate)
            np.testing.assert_array_equal(
                sample_trajectory(step.trajectory, rate, loaded.base_dir),
                sinusoid_deg(t, (hi + lo) / 2.0, amplitude, period),
            )
    cal = next(s for s in plan.steps if isinstance(s, CalibrationCheckStep))
    t = np.arange(0.0, 1.0 + 0.6 + 4.0, 1.0 / rate)
    np.testing.assert_array_equal(
        sample_trajectory(cal.trajectory, rate, loaded.base_dir),
        calibration_step_deg(t, 20.0, 45.0, 1.0, 0.6),
    )
