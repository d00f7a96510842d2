"""Facts about sending a planned motion (`hardware/motion.py`): approach, trajectory and exit go out in one
paced loop, every written sample is inside the envelope across the junctions, a stop brakes and parks, and
the recording of the trajectory part has the time base of a bare run. Shown with the tiny fake boards of
test_rig.py."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import Interrupted
from protocol_runner.hardware.conversions import volts_to_angle
from protocol_runner.hardware.motion import plan_motion, run_motion
from protocol_runner.hardware.safety import SafetyViolation
from protocol_runner.hardware.stream import APPROACH, EXIT, STOP, TRAJECTORY
from protocol_runner.protocol.trajectories import sinusoid_deg

from .test_rig import KNEE, LIMITS, make_rig

RATE_HZ = 100.0


def written_deg(ao) -> np.ndarray:  # type: ignore[no-untyped-def]
    """The angles the fake board was sent (no command table in these joints: Eq 1 inverted)."""
    return volts_to_angle(np.array([w[2] for w in ao.writes]), KNEE.range_deg)


def peak_accel(deg: np.ndarray) -> float:
    return float(np.max(np.abs(np.diff(deg, 2)))) * RATE_HZ**2


def sinusoid(seconds: float = 6.0) -> np.ndarray:
    # 65 ± 60 deg at 50 deg/s: starts at its peak speed, as every Eq 24 sinusoid does
    period = 2 * np.pi * 60.0 / 50.0
    return sinusoid_deg(np.arange(0.0, seconds, 1 / RATE_HZ), 65.0, 60.0, period)


def test_a_sinusoid_starts_and_ends_within_the_acceleration_limit_in_one_loop() -> None:
    rig, ao, ai, _ = make_rig()
    cmd = sinusoid()
    rec = run_motion(rig, [cmd], where="trial:k01:on:1")[0]
    sent = written_deg(ao)
    # one scan, one loop: no pause between approach, trajectory and exit (a pause holds the output)
    assert ai.stops == 1 and len(ai.started) == 1
    write_times = np.array([w[0] for w in ao.writes])
    np.testing.assert_allclose(np.diff(write_times), 1 / RATE_HZ, atol=1e-9)
    # from the park angle at rest to the park angle at rest, every junction inside the envelope (the old
    # approach ended at rest and the sinusoid started at 50 deg/s: 5,000 deg/s² in one tick)
    held = np.concatenate([[LIMITS.park_angle_deg], sent, [sent[-1]]])
    assert peak_accel(held) <= LIMITS.max_accel_deg_s2 * (1 + 1e-9)
    assert np.max(np.abs(np.diff(held))) * RATE_HZ <= LIMITS.max_rate_deg_s
    assert sent[0] == pytest.approx(LIMITS.park_angle_deg, abs=1e-3)
    assert sent[-1] == pytest.approx(LIMITS.park_angle_deg, abs=1e-3)
    assert rig.last_command_deg[0] == LIMITS.park_angle_deg
    # the recording is the trajectory part, on a bare run's time base
    np.testing.assert_array_equal(rec.command_deg, cmd)
    np.testing.assert_allclose(rec.command_time_s, np.arange(cmd.size) / RATE_HZ, atol=1e-12)
    assert rec.input_time_s[0] == pytest.approx(0.0, abs=1e-9)
    assert rec.input_time_s[-1] == pytest.approx(cmd.size / RATE_HZ, abs=1e-9)
    np.testing.assert_allclose(np.diff(rec.input_time_s), 1e-3, atol=1e-9)
    # ... with the whole commanded stream attached, for the archive
    np.testing.assert_allclose(rec.stream_deg, written_deg(ao), atol=130 / 65535)
    np.testing.assert_array_equal(rec.stream_deg[rec.stream_segment == TRAJECTORY], cmd)
    first = int(np.argmax(rec.stream_segment == TRAJECTORY))
    assert rec.stream_time_s[first] == 0.0 and rec.stream_time_s[0] < 0.0
    assert list(np.unique(rec.stream_segment)) == [APPROACH, TRAJECTORY, EXIT]


def test_the_approach_arrives_with_the_trajectory_s_starting_velocity() -> None:
    rig, _, _, _ = make_rig()
    cmd = sinusoid(2.0)
    stream = plan_motion(rig, [cmd])
    i = stream.first
    arriving = (stream.streams[0].command_deg[i] - stream.streams[0].command_deg[i - 1]) * RATE_HZ
    leaving = (cmd[1] - cmd[0]) * RATE_HZ
    assert leaving == pytest.approx(50.0, rel=1e-3)
    assert abs(arriving - leaving) * RATE_HZ <= LIMITS.max_accel_deg_s2 * (1 + 1e-9)


def test_a_stop_mid_trajectory_brakes_within_the_limit_then_parks() -> None:
    rig, ao, ai, _ = make_rig()
    cmd = sinusoid()
    stream = plan_motion(rig, [cmd])
    k = (
        stream.first // 10 + 5
    ) * 10  # the stop is seen at the read after sample k - 1 (50 ms into the trial)
    polls = {"n": 0}

    def stop_mid_trajectory() -> bool:
        polls["n"] += 1
        return polls["n"] == k // 10

    with pytest.raises(Interrupted, match="stopped on request") as info:
        run_motion(rig, [cmd], where="trial:k01:on:2", stop_requested=stop_mid_trajectory)
    sent = written_deg(ao)
    # the first k samples as planned, then (same loop, no pause) the brake and the parking ramp
    np.testing.assert_allclose(sent[:k], stream.streams[0].command_deg[:k], atol=130 / 65535)
    assert sent.size > k and ai.stops == 1
    speed_at_stop = abs(stream.streams[0].command_deg[k - 1] - stream.streams[0].command_deg[k - 2]) * RATE_HZ
    assert speed_at_stop > 45.0  # it was moving at about the sinusoid's peak speed
    held = np.concatenate([sent, [sent[-1]]])
    assert peak_accel(held) <= LIMITS.max_accel_deg_s2 * (1 + 1e-6)  # 16-bit codes: a little rounding
    assert np.max(np.abs(np.diff(held))) * RATE_HZ <= LIMITS.max_rate_deg_s
    assert rig.last_command_deg[0] == LIMITS.park_angle_deg
    partial = info.value.partial_recording[0]  # type: ignore[attr-defined]
    assert STOP in set(partial.stream_segment.tolist())
    assert partial.stream_deg[-1] == LIMITS.park_angle_deg


def test_a_stream_that_cannot_be_stopped_in_range_is_refused_before_any_write() -> None:
    """Starting at the range limit while already moving inwards at 100 deg/s needs an approach from
    beyond the limit (or a jump): refused, nothing sent."""
    rig, ao, ai, _ = make_rig()
    cmd = np.linspace(0.0, 30.0, 31)  # 0 -> 30 deg at 100 deg/s from the joint's lower limit
    with pytest.raises(SafetyViolation, match=r"approach") as info:
        run_motion(rig, [cmd], where="step-9")
    assert info.value.limit == "joint angle" and info.value.exit_code == 4
    assert ao.writes == [] and ai.started == []


def test_a_board_failure_keeps_the_trajectory_part_written_so_far() -> None:
    rig, _, _, _ = make_rig(fail_at_write=250)
    cmd = sinusoid()
    first = plan_motion(rig, [cmd]).first
    with pytest.raises(OSError) as info:
        run_motion(rig, [cmd], where="t")
    partial = info.value.partial_recording[0]  # type: ignore[attr-defined]
    assert partial.n_ticks == 250 - first
    np.testing.assert_array_equal(partial.command_deg, cmd[: 250 - first])
    assert partial.stream_deg.size == 250
