"""The safety invariant: for every trajectory kind and random levels within a rig's
limits, the complete commanded stream - approach, trajectory, exit to park, and a stop at a random
instant - stays within range, rate and acceleration limits, or the plan is refused before the run.

The limits are checked here independently of `check_trajectory`: rate = first difference x rate,
acceleration = second difference x rate^2, on every sample that would be sent, junctions included.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, note, settings
from hypothesis import strategies as st

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.safety import SafetyLimits, SafetyViolation, check_trajectory
from protocol_runner.hardware.stream import (
    APPROACH,
    EXIT,
    STOP,
    TRAJECTORY,
    CommandStream,
    build_stream,
    check_stream,
)
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.protocol.trajectories import TrajectoryFile, sinusoid_period_s
from protocol_runner.protocol.trajectory_record import Trajectory

REL_TOL = 1e-9  # the limits' own tolerance (hardware/safety.py): a ramp at exactly the limit passes
KINDS = ("sinusoid", "human", "identification", "step", "hold")


def assert_within(sent: np.ndarray, limits: SafetyLimits, rate_hz: float) -> None:
    lo, hi = limits.range_deg
    assert np.all(np.isfinite(sent))
    assert sent.min() >= lo - 1e-9 and sent.max() <= hi + 1e-9, (sent.min(), sent.max())
    if sent.size > 1:
        rate = np.abs(np.diff(sent)) * rate_hz
        assert rate.max() <= limits.max_rate_deg_s * (1 + REL_TOL), rate.max()
    if sent.size > 2:
        accel = np.abs(np.diff(sent, 2)) * rate_hz**2
        assert accel.max() <= limits.max_accel_deg_s2 * (1 + REL_TOL), accel.max()


@st.composite
def rig_limits(draw: st.DrawFn) -> tuple[SafetyLimits, float]:
    lo = draw(st.floats(0.0, 40.0))
    hi = draw(st.floats(lo + 20.0, 130.0))
    max_rate = draw(st.floats(20.0, 200.0))
    limits = SafetyLimits(
        range_deg=(lo, hi),
        max_rate_deg_s=max_rate,
        max_accel_deg_s2=draw(st.floats(100.0, 5000.0)),
        park_angle_deg=draw(st.floats(lo, hi)),
        park_rate_deg_s=draw(st.floats(1.0, max_rate)),
    )
    return limits, draw(st.sampled_from([50.0, 100.0, 200.0]))


@st.composite
def trajectories(
    draw: st.DrawFn, limits: SafetyLimits, rate_hz: float, kinds: tuple[str, ...] = KINDS
) -> tuple[str, np.ndarray]:
    """A trajectory of a random kind with random levels inside the joint range; sinusoids, steps, holds and
    smooth human files also inside the rate and acceleration limits (as the plan's own checks require);
    identification trajectories and corner-cutting human files as they come."""
    kind = draw(st.sampled_from(kinds))
    lo, hi = limits.range_deg
    if kind == "sinusoid":
        a = draw(st.floats(1.0, (hi - lo) / 2))
        mean = draw(st.floats(lo + a, max(lo + a, hi - a)))  # equal bounds may round the wrong way
        # speed within the rate limit and peak acceleration (speed^2 / amplitude) within the limit
        top = min(limits.max_rate_deg_s, math.sqrt(limits.max_accel_deg_s2 * a)) * 0.999
        speed = draw(st.floats(min(1.0, top), top))
        period = sinusoid_period_s(a, speed)
        n = draw(st.floats(0.3, 3.0))
        traj = Trajectory("sinusoid", n * period, mean_deg=mean, amplitude_deg=a, period_s=period)
        return kind, sample_trajectory(traj, rate_hz, Path("."))
    if kind == "step":
        start = draw(st.floats(lo, hi))
        step = draw(st.floats(lo, hi)) - start
        # raised cosine: peak rate pi/2 step/ramp, peak acceleration pi^2/2 step/ramp^2
        need = max(
            math.pi / 2 * abs(step) / limits.max_rate_deg_s,
            math.sqrt(math.pi**2 / 2 * abs(step) / limits.max_accel_deg_s2),
        )
        ramp = draw(st.floats(need * 1.01 + 0.02, need * 3 + 0.05))
        params = (
            ("from_deg", start),
            ("step_deg", step),
            ("settle_s", draw(st.floats(0, 1))),
            ("ramp_s", ramp),
        )
        traj = Trajectory("ramped_step", params[2][1] + ramp + draw(st.floats(0.05, 2.0)), params=params)
        return kind, sample_trajectory(traj, rate_hz, Path("."))
    if kind == "hold":
        return kind, np.full(draw(st.integers(1, 300)), draw(st.floats(lo, hi)))
    if kind == "identification":
        a_min = draw(st.floats(lo, hi - 2.0))
        a_max = draw(st.floats(a_min + 1.5, hi))
        rep = draw(st.floats(2.0, 30.0))
        params = (
            ("min_deg", a_min),
            ("max_deg", a_max),
            ("repetition_s", rep),
            ("initial_period_s", draw(st.floats(1.0, 10.0))),
            ("final_period_s", draw(st.floats(1.0, 10.0))),
        )
        traj = Trajectory("identification", draw(st.floats(0.5, 2.5)) * rep, params=params)
        return kind, sample_trajectory(traj, rate_hz, Path("."))
    # human: an angle-vs-time file sampled at its own rate, interpolated as a file is
    if draw(st.booleans()):  # hostile: random knots, corners included
        n = draw(st.integers(2, 12))
        dt_knots = draw(st.lists(st.floats(0.05, 2.0), min_size=n - 1, max_size=n - 1))
        time_s = np.concatenate([[0.0], np.cumsum(dt_knots)])
        angles = np.array(draw(st.lists(st.floats(lo, hi), min_size=n, max_size=n)))
    else:  # smooth, like a recorded knee motion: two sinusoids within the range, rate and acceleration
        time_s = np.arange(0.0, draw(st.floats(1.0, 20.0)), 1.0 / draw(st.sampled_from([30.0, 100.0, 120.0])))
        w1, w2 = draw(st.floats(0.2, 3.0)), draw(st.floats(0.2, 3.0))
        p1, p2 = draw(st.floats(0, 2 * math.pi)), draw(st.floats(0, 2 * math.pi))
        shape = 0.5 * (np.sin(w1 * time_s + p1) + np.sin(w2 * time_s + p2))  # within [-1, 1]
        a = draw(st.floats(0.5, (hi - lo) / 2))
        a = min(
            a, 0.5 * limits.max_rate_deg_s / max(w1, w2), 0.5 * limits.max_accel_deg_s2 / max(w1, w2) ** 2
        )
        mean = draw(st.floats(lo + a, hi - a))
        angles = mean + a * shape
    f = TrajectoryFile(Path("synthetic.csv"), time_s, angles, "")
    return kind, f.at(np.arange(0.0, f.duration_s, 1.0 / rate_hz))


def plan(cmd: np.ndarray, limits: SafetyLimits, rate_hz: float) -> CommandStream | SafetyViolation:
    """The stream, or the refusal (what the preflight and the rig do before anything is sent)."""
    try:
        stream = build_stream(cmd, limits, rate_hz)
        check_stream(stream, limits, where="property")
    except SafetyViolation as exc:
        note(f"refused: {exc}")
        return exc
    return stream


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_every_commanded_sample_stays_inside_the_envelope_or_the_plan_is_refused(data: st.DataObject) -> None:
    limits, rate_hz = data.draw(rig_limits())
    kind, cmd = data.draw(trajectories(limits, rate_hz))
    note(f"{kind}: {cmd.size} samples, limits {limits}, {rate_hz} Hz")
    stream = plan(cmd, limits, rate_hz)
    if isinstance(stream, SafetyViolation):
        event(f"{kind}: refused")
        # A refusal is never a junction's rate or acceleration: it happens when the trajectory itself breaks
        # the envelope, or when reaching its start (or stopping) at the acceleration limit - the shortest
        # possible - would leave the range, which no plan can avoid.
        try:
            check_trajectory(cmd, rate_hz, limits, where="trajectory alone")
        except SafetyViolation:
            return
        assert stream.limit == "joint angle", f"a junction broke the envelope: {stream}"
        return
    event(f"{kind}: accepted")
    sent = stream.command_deg
    # the stream starts at rest at the park angle, carries the trajectory unchanged, ends parked at rest
    assert sent[0] == limits.park_angle_deg and sent[-1] == limits.park_angle_deg
    np.testing.assert_array_equal(sent[stream.segment == TRAJECTORY], cmd)
    assert set(np.unique(stream.segment)) <= {APPROACH, TRAJECTORY, EXIT}
    assert_within(np.concatenate([[sent[0]], sent, [sent[-1]]]), limits, rate_hz)  # at rest at both ends

    # a stop requested after a random number of written samples: brake, then park
    written = data.draw(st.integers(0, sent.size), label="samples written before the stop")
    tail, codes = stream.stop_after(written, limits)
    actual = np.concatenate([[sent[0]], sent[:written], tail])
    # then the output holds its last sample: that junction is checked too
    assert_within(np.append(actual, actual[-1]), limits, rate_hz)
    assert actual[-1] == limits.park_angle_deg
    if written < stream.exit_start and tail.size:
        assert set(np.unique(codes)) == {STOP}


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_trajectories_inside_the_limits_are_never_refused(data: st.DataObject) -> None:
    """Sinusoids, calibration steps and holds within the range, rate and acceleration limits always get a
    plan: the approach matches their starting velocity and every stop brakes before their own turning
    point."""
    limits, rate_hz = data.draw(rig_limits())
    _, cmd = data.draw(trajectories(limits, rate_hz, ("sinusoid", "step", "hold")))
    stream = plan(cmd, limits, rate_hz)
    assert isinstance(stream, CommandStream), str(stream)


@pytest.mark.parametrize(
    ("trajectory", "message"),
    [
        (np.full(10, 100.0), "parking ramp: moving 55 deg .* would take"),  # from rest: the ramp
        (np.linspace(50.0, 51.0, 10), "braking from 11.1111 deg/s .* takes more than"),  # moving: the brake
    ],
)
def test_limits_too_small_to_move_the_joint_are_refused_with_bounded_work(
    trajectory: np.ndarray, message: str
) -> None:
    """max_accel_deg_s2 = 1e-9 would need a ramp of 10^10 samples: refused at once, nothing allocated."""
    limits = SafetyLimits((0.0, 130.0), 120.0, 1e-9, 45.0, 20.0)
    with pytest.raises(InvalidInput, match=message):
        build_stream(trajectory, limits, 100.0)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_a_dry_run_sends_exactly_the_checked_streams_or_nothing(data: st.DataObject) -> None:
    """In a dry run the rig's paced loop drives the simulated boards: what reaches the simulated board on
    each joint's channel (one joint or several), sample for sample, is that joint's checked stream up to a
    random stop and then its checked stop tail, every sample inside that joint's range, rate and
    acceleration limits - or nothing at all on any channel when a joint's plan is refused. Parking the rig
    afterwards from random angles sends only samples inside the limits too."""
    from protocol_runner.errors import Interrupted
    from protocol_runner.hardware.conversions import volts_to_ao16_code
    from protocol_runner.hardware.joint import JointConfig
    from protocol_runner.hardware.motion import run_motion
    from protocol_runner.hardware.rig import READ_EVERY_TICKS
    from protocol_runner.hardware.simulator.daq import SimulatedRig
    from protocol_runner.hardware.stream import build_motion_stream, check_motion_stream

    n_joints = data.draw(st.integers(1, 3), label="joints")
    limits, rate_hz = data.draw(rig_limits())
    all_limits = [limits] + [data.draw(rig_limits())[0] for _ in range(n_joints - 1)]
    cmds = [
        data.draw(trajectories(lim, rate_hz, ("sinusoid", "step", "hold", "human")))[1] for lim in all_limits
    ]
    n = min(c.size for c in cmds)  # the joints share the trial's time
    cmds = [c[:n] for c in cmds]
    joints = [
        JointConfig(
            name=f"joint{k}",
            range_deg=(0.0, 130.0),
            torque_range_nm=(-84.8, 84.8),
            output_channel=k,
            angle_input_channel=2 * k,
            torque_input_channel=2 * k + 1,
            output_rate_hz=rate_hz,
            limits=lim,
        )
        for k, lim in enumerate(all_limits)
    ]
    sim = SimulatedRig(joints, seed=1)
    rig = sim.make_rig()
    stream = build_motion_stream(rig.names, cmds, all_limits, rate_hz)
    tables, ranges = [None] * n_joints, [j.range_deg for j in joints]
    try:
        check_motion_stream(
            stream, all_limits, where="property", command_tables=tables, volts_ranges_deg=ranges
        )
        refused = False
    except SafetyViolation:
        refused = True
    polls_until_stop = data.draw(st.integers(1, 1000), label="polls before a stop request")
    polls = {"n": 0}

    def stop() -> bool:
        polls["n"] += 1
        return polls["n"] >= polls_until_stop

    try:
        run_motion(rig, cmds, where="property", stop_requested=stop)
    except SafetyViolation:
        assert refused
        assert sim.ao.records()[0].size == 0  # refused before anything was written
        return
    except Interrupted:
        pass
    assert not refused
    full = stream.command_deg()
    written = min(polls_until_stop * READ_EVERY_TICKS, full.shape[0])
    tail, _ = stream.stop_after(written, all_limits) if written < full.shape[0] else (full[:0], None)
    expected = np.concatenate([full[:written], tail])
    _, channel, code = sim.ao.records()
    for k, j in enumerate(joints):
        assert_within(np.concatenate([[j.limits.park_angle_deg], expected[:, k]]), j.limits, rate_hz)
        sent = code[channel == k][1:]  # after the channel's configuration (0 V)
        np.testing.assert_array_equal(sent, volts_to_ao16_code(j.command_to_volts(expected[:, k])))

    # parking from anywhere in the range: every joint's ramp stays inside its limits
    starts = [data.draw(st.floats(*lim.range_deg), label="park from") for lim in all_limits]
    sim.ao.clear_records()
    parks = rig.park(from_deg=starts)
    _, channel, code = sim.ao.records()
    for k, (j, rec) in enumerate(zip(joints, parks, strict=True)):
        ramp = rec.command_deg
        assert_within(
            np.concatenate([[starts[k]], ramp, [ramp[-1]]]), j.limits, rate_hz
        )  # at rest at both ends
        assert ramp[-1] == j.limits.park_angle_deg
        np.testing.assert_array_equal(code[channel == k], volts_to_ao16_code(j.command_to_volts(ramp)))
