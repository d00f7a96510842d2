"""The simulator's block path (issue 20): in simulated time the rig sends up to `BLOCK_S` of already-checked
samples and reads the scan in one compiled call (`SimulatedRig.send_block`: output codes, commands, plant,
sensors and input codes together) instead of one `write_volts` per tick and a scan read every 10 ticks. It must give exactly the data of the per-tick loop for the same seed (every code,
volt, time and the plant's state), stop after the same sample, never receive a sample the envelope did not
pass, and leave the real boards (and --realtime) on the paced per-tick loop."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.errors import Interrupted, InvalidInput
from protocol_runner.hardware.motion import plan_motion, run_motion
from protocol_runner.hardware.rig import BLOCK_S, READ_EVERY_TICKS, Rig, TrialRecording, block_end
from protocol_runner.hardware.safety import SafetyViolation
from protocol_runner.hardware.simulator import SimulatedRig
from protocol_runner.protocol.plan import Trajectory
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.protocol.trajectories import sinusoid_period_s

from ..knee_device import KNEE_PARAMS, knee_brace
from ..knee_rig import knee_joint_config

RATE_HZ = 100.0
JOINT = knee_joint_config(max_rate_deg_s=120.0, max_accel_deg_s2=2000.0)  # the knee protocol's envelope


def knee_sinusoid(speed_deg_s: float = 50.0, periods: float = 2.0) -> np.ndarray:
    """Appendix A sinusoid over 20-110 deg (Eq 24-25), as a trial samples it."""
    a = 45.0
    period = sinusoid_period_s(a, speed_deg_s)
    traj = Trajectory("sinusoid", periods * period, mean_deg=65.0, amplitude_deg=a, period_s=period)
    return sample_trajectory(traj, RATE_HZ, Path("."))


def calibration_step() -> np.ndarray:
    """Appendix A calibration: a 45 deg raised-cosine step from 20 deg, held (the knee protocol's values)."""
    params = (("from_deg", 20.0), ("step_deg", 45.0), ("settle_s", 1.0), ("ramp_s", 0.6))
    return sample_trajectory(Trajectory("ramped_step", 5.6, params=params), RATE_HZ, Path("."))


KNEE_BRACE = knee_brace((40.0, 90.0), 3.75, 13.0, 3)  # R1 stops, friction level 2, K2, centre preload
CASES = {
    "knee trial (brace on)": (KNEE_BRACE, knee_sinusoid),
    "brace-off trial": (None, knee_sinusoid),
    "calibration step": (None, calibration_step),
    "half-speed trial": (knee_brace((0.0, 130.0), 6.25, 20.0, 1), lambda: knee_sinusoid(25.0, 1.3)),
}


def simulated(*, blocks: bool, device: object = None) -> tuple[SimulatedRig, Rig]:
    sim = SimulatedRig(JOINT, seed=2007, params=KNEE_PARAMS, scheduled_blocks=blocks)
    sim.set_device(device)  # type: ignore[arg-type]
    return sim, sim.make_rig()


def assert_same_recording(a: TrialRecording, b: TrialRecording) -> None:
    for f in dataclasses.fields(TrialRecording):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
            assert x is not None and y is not None, f.name
            assert x.dtype == y.dtype and x.shape == y.shape, f.name
            np.testing.assert_array_equal(x, y, err_msg=f.name)  # bit for bit (NaN-free arrays)
        else:
            assert x == y, f.name


def assert_same_boards(a: SimulatedRig, b: SimulatedRig) -> None:
    for x, y in zip(a.ao.records(), b.ao.records(), strict=True):
        np.testing.assert_array_equal(x, y)
    assert a.clock.now_s() == b.clock.now_s()
    assert (a.plant.step, a.plant.angle_deg, a.plant.load_nm) == (
        b.plant.step,
        b.plant.angle_deg,
        b.plant.load_nm,
    )


@pytest.mark.parametrize("case", list(CASES))
def test_the_block_path_gives_the_per_tick_data_bit_for_bit(case: str) -> None:
    device, trajectory = CASES[case]
    cmd = trajectory()
    out = {}
    for blocks in (False, True):
        sim, rig = simulated(blocks=blocks, device=device)
        sim.clock.advance(12.345)  # a step that starts at an arbitrary clock reading
        sim.begin_step(f"trial:{case}")
        first = run_motion(rig, cmd, where=case)
        second = run_motion(rig, cmd[::-1].copy(), where=case)  # from where the first left the joint
        parked = rig.park(from_deg=None)
        out[blocks] = (sim, rig, first, second, parked)
    (sim_t, rig_t, *per_tick), (sim_b, rig_b, *block) = out[False], out[True]
    for a, b in zip(per_tick, block, strict=True):
        assert_same_recording(a, b)
    assert_same_boards(sim_t, sim_b)
    assert rig_t.last_command_deg == rig_b.last_command_deg
    # and it is a real trial: the joint followed the command through the transition and the brace
    assert per_tick[0].n_ticks == cmd.size and np.ptp(per_tick[0].angle_deg) > 20.0


def test_the_block_path_makes_one_write_per_block_of_at_most_one_second() -> None:
    sim, rig = simulated(blocks=True, device=KNEE_BRACE)
    sim.begin_step("count")
    calls: list[int] = []
    send_block = sim.send_block

    def counting(channel: int, times_s: np.ndarray, volts: np.ndarray):  # type: ignore[no-untyped-def]
        calls.append(times_s.size)
        assert times_s[-1] - times_s[0] < BLOCK_S  # <= BLOCK_S of robot time per compiled call
        return send_block(channel, times_s, volts)

    sim.send_block = counting  # type: ignore[method-assign]
    cmd = knee_sinusoid()
    stream = plan_motion(rig, cmd)
    run_motion(rig, cmd, where="count")
    assert sum(calls) == stream.command_deg.size
    assert max(calls) == int(RATE_HZ * BLOCK_S)
    assert len(calls) == -(-stream.command_deg.size // int(RATE_HZ * BLOCK_S))


@pytest.mark.parametrize("polls_before_stop", [1, 7, 10, 11, 23])
def test_a_stop_request_stops_after_the_same_sample_on_both_paths(polls_before_stop: int) -> None:
    cmd = knee_sinusoid()
    got = {}
    for blocks in (False, True):
        sim, rig = simulated(blocks=blocks, device=KNEE_BRACE)
        sim.begin_step("stop")
        polls = {"n": 0}

        def stop(polls: dict[str, int] = polls) -> bool:
            polls["n"] += 1
            return polls["n"] >= polls_before_stop

        with pytest.raises(Interrupted, match="stopped on request") as info:
            run_motion(rig, cmd, where="stop", stop_requested=stop)
        got[blocks] = (sim, rig, info.value.partial_recording, polls["n"], str(info.value))  # type: ignore[attr-defined]
    (sim_t, _, rec_t, n_t, msg_t), (sim_b, rig_b, rec_b, n_b, msg_b) = got[False], got[True]
    assert n_t == n_b == polls_before_stop  # polled at the same boundaries, never after the stop
    assert msg_t == msg_b
    assert_same_recording(rec_t, rec_b)
    assert_same_boards(sim_t, sim_b)
    stop_sample = polls_before_stop * READ_EVERY_TICKS
    np.testing.assert_array_equal(
        rec_b.stream_deg[:stop_sample], plan_motion(rig_b, cmd).command_deg[:stop_sample]
    )
    assert rig_b.last_command_deg == JOINT.limits.park_angle_deg  # braked and parked in the same loop


def test_block_end_polls_where_the_per_tick_loop_polls() -> None:
    seen: list[int] = []
    polls = iter(range(1000))

    def never() -> bool:
        seen.append(next(polls))
        return False

    assert block_end(0, 95, 100, never) == (95, False)
    assert len(seen) == 10  # boundaries 10, 20, ..., 90, 95: one poll per read of the per-tick loop
    assert block_end(100, 1000, 100, lambda: True) == (110, True)  # the first boundary that asks
    assert block_end(40, 1000, 100, None) == (140, False)


@pytest.mark.parametrize(
    ("start", "n", "block_ticks"), [(0, 95, 100), (100, 1000, 100), (40, 1000, 1000), (0, 7, 10)]
)
def test_a_stop_flag_is_asked_once_per_block_and_ends_it_where_polling_would(
    start: int, n: int, block_ticks: int
) -> None:
    """The session's StopFlag answers the same however often it is asked: one poll per block, with the
    block's end and verdict those of polling at every boundary."""
    from protocol_runner.session.signals import StopFlag

    for is_set in (False, True):
        flag = StopFlag()
        if is_set:
            flag.request("test")
        asked: list[bool] = []

        def counted(flag: StopFlag = flag, asked: list[bool] = asked) -> bool:
            asked.append(True)
            return flag()

        assert block_end(start, n, block_ticks, flag) == block_end(start, n, block_ticks, counted)
        polls = 0

        class Counting(StopFlag):
            def __call__(self) -> bool:
                nonlocal polls
                polls += 1
                return super().__call__()

        counting = Counting()
        if is_set:
            counting.request("test")
        block_end(start, n, block_ticks, counting)
        assert polls == 1
        assert len(asked) == (1 if is_set else -(-(min(start + block_ticks, n) - start) // 10))


def test_a_trajectory_outside_the_envelope_is_refused_before_the_block_path_writes() -> None:
    sim, rig = simulated(blocks=True)
    sim.begin_step("unsafe")
    too_fast = 45.0 + 40.0 * np.sin(2 * np.pi * np.arange(300) / 100.0)  # 250 deg/s peak > 120
    with pytest.raises(SafetyViolation):
        run_motion(rig, too_fast, where="unsafe")
    with pytest.raises(SafetyViolation):
        rig.run_trajectory(too_fast, where="unsafe")
    assert sim.ao.records()[0].size == 0  # nothing reached the board, not even the channel set-up


def test_the_block_writes_are_the_checked_stream_and_the_codes_of_write_volts() -> None:
    sim, rig = simulated(blocks=True, device=KNEE_BRACE)
    sim.begin_step("stream")
    cmd = knee_sinusoid()
    stream = plan_motion(rig, cmd)
    rec = run_motion(rig, cmd, where="stream")
    _, channel, code = sim.ao.records()
    sent = code[channel == JOINT.output_channel][1:]  # after the channel's configuration (0 V)
    np.testing.assert_array_equal(rec.stream_deg, stream.command_deg)
    volts = JOINT.command_to_volts(stream.command_deg)
    one_by_one = SimulatedRig(JOINT).ao
    np.testing.assert_array_equal(sent, [one_by_one.write_volts(8, float(v)) for v in volts])


def test_send_block_codes_match_write_volts_at_ties_full_scale_and_beyond() -> None:
    volts = np.array(
        [0.0, 10.0, -10.0, 12.0, -12.0, np.inf, -np.inf, 0.5 / 3276.8, 1.5 / 3276.8, -2.5 / 3276.8]
    )
    volts = np.concatenate(
        [volts, np.linspace(-10.0, 10.0, 4001), np.arange(-20, 21) / 3276.8 + 0.5 / 3276.8]
    )
    blocks, single = SimulatedRig(JOINT), SimulatedRig(JOINT)
    times = np.arange(volts.size) * 0.01
    codes, _ = blocks.send_block(3, times, volts)  # a channel that moves nothing
    np.testing.assert_array_equal(codes, [single.ao.write_volts(3, float(v)) for v in volts])
    codes, _ = blocks.send_block(8, times + times[-1] + 0.01, volts)  # the joint's own channel
    np.testing.assert_array_equal(codes, [single.ao.write_volts(8, float(v)) for v in volts])


def test_send_block_refuses_nan_and_the_past_before_anything_changes() -> None:
    sim = SimulatedRig(JOINT, params=KNEE_PARAMS)
    rig = sim.make_rig()
    sim.begin_step("refusals")
    rig.ai.start_scan(rig.scan_channels, 1000.0)
    sim.clock.advance(1.0)
    before = (sim.plant.step, sim.plant.angle_deg)
    with pytest.raises(InvalidInput, match="NaN"):
        sim.send_block(8, np.array([1.0, 1.01]), np.array([0.0, np.nan]))
    with pytest.raises(InvalidInput, match="time order"):
        sim.send_block(8, np.array([0.5, 1.01]), np.array([0.0, 0.0]))
    with pytest.raises(InvalidInput, match="time order"):
        sim.send_block(8, np.array([1.02, 1.01]), np.array([0.0, 0.0]))
    assert sim.ao.records()[0].size == 0 and sim.clock.now_s() == 1.0
    assert (sim.plant.step, sim.plant.angle_deg) == before
    # and the scan is where it was: the next read returns every row since the start (1001 rows)
    assert rig.ai.read_available().n_samples == 1001


def test_realtime_and_real_boards_keep_the_per_tick_loop() -> None:
    assert SimulatedRig(JOINT, realtime=True).make_rig()._block_output() is None
    assert SimulatedRig(JOINT, scheduled_blocks=False).make_rig()._block_output() is None
    assert SimulatedRig(JOINT).make_rig()._block_output() is not None
    assert (
        Rig(JOINT, SimulatedRig(JOINT).ao, SimulatedRig(JOINT).ai, SimulatedRig(JOINT).clock).block_io is None
    )
    sim = SimulatedRig(JOINT)
    rig = sim.make_rig()
    rig.ai = SimulatedRig(JOINT).ai  # a board replaced (or wrapped, as fault injection does)
    assert rig._block_output() is None
    with pytest.raises(InvalidInput, match="simulated time"):
        SimulatedRig(JOINT, realtime=True).send_block(8, np.array([1e9]), np.array([0.0]))
