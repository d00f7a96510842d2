"""The watchdog on measured signals, against the simulator with injected faults: a jammed brace (range-of-
motion stops closed around the park angle) and a misplaced stop (inside the commanded motion). The
watchdog stops the motion within its declared time, brakes and parks in the same loop, and names the
joint, the value and the limit; without the fault the same motion runs to its end."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from protocol_runner.errors import EXIT_STOPPED_BY_CHECK, WatchdogTripped
from protocol_runner.hardware.motion import run_motion
from protocol_runner.hardware.rig import READ_EVERY_TICKS
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.stream import STOP
from protocol_runner.hardware.watchdog import watchdog_limits

from ..knee_rig import KNEE_PARK_DEG, KNEE_TORQUE_LIMIT_NM, knee_joint_config

MAX_ERROR_DEG = 10.0
MAX_ERROR_S = 0.5
LAG_S = 0.2


def knee(torque_margin: float = 1.0) -> SimulatedRig:
    joint = knee_joint_config(max_rate_deg_s=120.0, max_accel_deg_s2=2000.0)
    watch = watchdog_limits(
        joint.torque_range_nm,
        torque_margin=torque_margin,
        max_tracking_error_deg=MAX_ERROR_DEG,
        max_tracking_error_s=MAX_ERROR_S,
        lag_s=LAG_S,
    )
    sim = SimulatedRig([replace(joint, watchdog=watch)], seed=3)
    # the simulated board hands its rows over in 1 s transfers; the rig's board hands them over at once:
    # give every read its rows, as on the rig
    sim.ai.transfer_s = 0.0
    return sim


def sine_deg(rate_hz: float = 100.0) -> np.ndarray:
    """Four cycles of 20..80 deg at 0.25 Hz, from and back to the park angle (20 deg)."""
    t = np.arange(0.0, 16.0, 1.0 / rate_hz)
    return KNEE_PARK_DEG + 30.0 * (1.0 - np.cos(2 * np.pi * 0.25 * t))


def stops(lo_deg: float, hi_deg: float) -> list[tuple[str, str, dict[str, object]]]:
    return [("fault", "rom_stops", {"range_deg": [lo_deg, hi_deg], "stop_stiffness_nm_per_deg": 40.0})]


def test_without_a_fault_the_motion_runs_to_its_end() -> None:
    sim = knee()
    rec = run_motion(sim.make_rig(), [sine_deg()], where="trial")[0]
    assert rec.command_deg.size == sine_deg().size
    assert np.max(rec.angle_deg) > 75.0


@pytest.mark.parametrize(("lo_deg", "hi_deg"), [(18.0, 22.0), (10.0, 50.0)], ids=["jammed", "misplaced stop"])
def test_a_joint_that_stops_following_is_stopped_within_the_declared_time(
    lo_deg: float, hi_deg: float
) -> None:
    sim = knee()
    sim.set_device(stops(lo_deg, hi_deg))
    rig = sim.make_rig()
    with pytest.raises(WatchdogTripped) as caught:
        run_motion(rig, [sine_deg()], where="trial")
    exc = caught.value
    assert exc.exit_code == EXIT_STOPPED_BY_CHECK
    assert (exc.joint, exc.quantity) == ("knee", "tracking error")
    assert abs(exc.value) > MAX_ERROR_DEG
    assert "knee" in exc.message and "10 deg" in exc.message and "0.5 s" in exc.message
    # from the recorded data: the fault's onset is the first sample whose tracking error (angle minus the
    # command delayed by the lag) exceeds the limit; the brake starts at most the declared time plus one
    # scan read later
    rec = exc.partial_recording[0]  # type: ignore[attr-defined]
    dt = 1.0 / rec.output_rate_hz
    delayed = np.interp(rec.input_time_s - LAG_S, rec.stream_time_s, rec.stream_deg, left=rec.stream_deg[0])
    beyond = np.abs(rec.angle_deg - delayed) > MAX_ERROR_DEG
    onset_s = float(rec.input_time_s[np.argmax(beyond)])
    assert beyond.any()
    brake_s = float(rec.stream_time_s[np.argmax(rec.stream_segment == STOP)])
    assert (rec.stream_segment == STOP).any()
    assert onset_s <= brake_s <= onset_s + MAX_ERROR_S + READ_EVERY_TICKS * dt + 2 * dt
    # the joint was parked in the same loop: the last command is the park angle
    assert rec.stream_deg[-1] == pytest.approx(KNEE_PARK_DEG)
    assert rig.last_command_deg[0] == pytest.approx(KNEE_PARK_DEG)
    # the stop's samples are never watched: parking a jammed joint does not trip again
    rig.park()
    # and once the fault is removed the same motion completes
    sim.set_device(None)
    run_motion(rig, [sine_deg()], where="trial (again)")


def test_a_torque_beyond_its_margin_is_stopped() -> None:
    sim = knee(torque_margin=0.5)
    sim.set_device(stops(10.0, 50.0))
    with pytest.raises(WatchdogTripped) as caught:
        run_motion(sim.make_rig(), [sine_deg()], where="trial")
    exc = caught.value
    assert (exc.joint, exc.quantity) == ("knee", "torque")
    assert abs(exc.value) > 0.5 * KNEE_TORQUE_LIMIT_NM
    assert f"{0.5 * KNEE_TORQUE_LIMIT_NM:g} N·m" in exc.message
