"""Several joints on one set of boards: the USB-3105 bytes of a three-channel tick, per-joint
safety refusal before any write, every joint parked on a stop, and every commanded sample of every joint
inside that joint's envelope (a property over random motions and stop times)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import Interrupted
from protocol_runner.hardware.motion import run_motion
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyViolation
from protocol_runner.hardware.simulator.daq import SimulatedRig
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.hardware.stream import STOP, TRAJECTORY, build_motion_stream
from protocol_runner.hardware.usb3105 import Usb3105
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.session.rigs import joint_config
from tests.fakeusb.backend import FakeBackend
from tests.fakeusb.usb3105 import AOUT, AOUT_SYNC, make_usb3105

REPO = Path(__file__).resolve().parents[2]
LEG = load_protocol(REPO / "protocols" / "leg_phase2.yaml")
JOINTS = [joint_config(LEG, r) for r in LEG.protocol.rigs]  # hip, knee, ankle (outputs 5, 8, 10)
PARAMS = [SimulatorParams(**dict(r.simulator)) for r in LEG.protocol.rigs]
RATE = 100.0


def _sim(seed: int = 3) -> SimulatedRig:
    return SimulatedRig(JOINTS, params=PARAMS, seed=seed)


def _gait(n: int) -> list[np.ndarray]:
    t = np.arange(n) / RATE
    return [
        20 + 10 * np.sin(2 * np.pi * t / 4),  # hip around its park angle 20
        45 + 20 * np.sin(2 * np.pi * t / 4),  # knee around 45
        0 + 8 * np.sin(2 * np.pi * t / 4),  # ankle around 0
    ]


def test_one_tick_of_three_joints_is_three_held_writes_latched_by_one_sync_on_the_wire() -> None:
    sim = _sim()
    model = make_usb3105()
    ao = Usb3105.open(backend=FakeBackend(model))
    rig = Rig(JOINTS, ao, sim.ai, sim.clock)
    rig.prepare()
    model.reports.clear()
    recs = rig.send(np.array([[30.0, 60.0, -10.0], [31.0, 61.0, -9.0]]), where="t", stop_requested=None)
    reports = model.reports
    assert len(reports) == 8  # per tick: AOUT x 3 (update = 1: wait for sync), then one AOUT_SYNC
    for tick in (0, 1):
        part = reports[4 * tick : 4 * tick + 4]
        assert [r[0] for r in part] == [AOUT, AOUT, AOUT, AOUT_SYNC]
        assert [r[1] for r in part[:3]] == [5, 8, 10]  # hip, knee, ankle outputs (joint n: output n-1)
        assert all(r[4] == 1 for r in part[:3])
        for r, rec in zip(part[:3], recs, strict=True):
            assert r[2] | (r[3] << 8) == rec.command_codes[tick]
    # Eq 1 on each joint's own range: knee 60 deg of [0, 130] -> -10 + 20 * 60/130 V
    assert model.pin_volts(8) == pytest.approx(-10 + 20 * 61 / 130, abs=1e-3)
    assert model.pin_volts(10) == pytest.approx(-10 + 20 * (-9 + 45) / 75, abs=1e-3)
    # one shared time base: every joint's recording has the same input and command times
    assert all(np.array_equal(r.input_time_s, recs[0].input_time_s) for r in recs)
    ao.close()


def test_a_violation_on_one_joint_is_refused_before_any_write_naming_it() -> None:
    sim = _sim()
    rig = sim.make_rig()
    hip, knee, ankle = _gait(800)
    ankle = ankle - 40.0  # reaches -48 deg: outside the ankle's [-45, 30]
    with pytest.raises(SafetyViolation, match="joint ankle_flexion"):
        run_motion(rig, [hip, knee, ankle], where="trial")
    assert sim.ao.records()[0].size == 0  # nothing was sent to any joint


def test_a_stop_request_brakes_and_parks_every_joint_in_the_same_loop() -> None:
    sim = _sim()
    rig = sim.make_rig()
    reads = {"n": 0}

    def stop() -> bool:  # Ctrl-C (SIGINT) arrives 2.5 s into the motion
        reads["n"] += 1
        return reads["n"] > 25

    with pytest.raises(Interrupted) as caught:
        run_motion(rig, _gait(1200), where="trial", stop_requested=stop)
    parks = [j.limits.park_angle_deg for j in JOINTS]
    assert rig.last_command_deg == pytest.approx(parks)
    partial = caught.value.partial_recording  # type: ignore[attr-defined]
    for rec, j in zip(partial, JOINTS, strict=True):
        assert (rec.stream_segment == STOP).any()
        assert rec.stream_deg[-1] == pytest.approx(j.limits.park_angle_deg)
    # the simulated joints themselves end at rest near their park angles
    _t, ch, code = sim.ao.records()
    for j in JOINTS:
        last = code[ch == j.output_channel][-1]
        assert (
            abs(
                (last - 32768) / 3276.8
                - (-10 + 20 * (j.limits.park_angle_deg - j.range_deg[0]) / (j.range_deg[1] - j.range_deg[0]))
            )
            < 1e-3
        )


def test_park_moves_every_joint_to_its_park_angle_together() -> None:
    sim = _sim()
    rig = sim.make_rig()
    run_motion(rig, _gait(300), where="trial")
    recs = rig.park(from_deg=[60.0, 100.0, 20.0], where="park")  # as if left elsewhere
    assert [r.command_deg[-1] for r in recs] == pytest.approx([j.limits.park_angle_deg for j in JOINTS])
    assert len({r.command_deg.size for r in recs}) == 1  # sent together, one tick each


@settings(max_examples=40, deadline=None)
@given(
    amplitude=st.tuples(*[st.floats(0.5, 1.0)] * 3),
    period_s=st.floats(1.5, 8.0),
    phase=st.tuples(*[st.floats(0.0, 6.28)] * 3),
    n=st.integers(2, 1500),
    stop_at=st.integers(0, 2000),
)
def test_every_sample_of_every_joint_stays_inside_that_joints_envelope(
    amplitude: tuple[float, float, float],
    period_s: float,
    phase: tuple[float, float, float],
    n: int,
    stop_at: int,
) -> None:
    t = np.arange(n) / RATE
    trajectories = []
    for a, ph, j in zip(amplitude, phase, JOINTS, strict=True):
        lo, hi = j.limits.range_deg
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        # slow enough for each joint's rate and acceleration limits at any range
        w = 2 * np.pi / max(period_s, 2 * np.pi * a * half / (0.9 * j.limits.max_rate_deg_s))
        w = min(w, np.sqrt(0.9 * j.limits.max_accel_deg_s2 / (a * half)))
        trajectories.append(mid + 0.95 * a * half * np.sin(w * t + ph))
    stream = build_motion_stream([j.name for j in JOINTS], trajectories, [j.limits for j in JOINTS], RATE)
    cmd = stream.command_deg()
    written = min(stop_at, cmd.shape[0])
    tail, _ = stream.stop_after(written, [j.limits for j in JOINTS])
    stopped = np.concatenate([cmd[:written], tail]) if written else cmd[:0]
    assert (stream.segment()[stream.first] == TRAJECTORY).all()  # every joint's first sample on one tick
    for k, j in enumerate(JOINTS):
        lim = j.limits
        for x in (cmd[:, k], stopped[:, k]):
            if x.size < 1:
                continue
            assert lim.range_deg[0] - 1e-9 <= x.min() and x.max() <= lim.range_deg[1] + 1e-9
            if x.size > 1:
                assert np.max(np.abs(np.diff(x))) * RATE <= lim.max_rate_deg_s * (1 + 1e-9)
            if x.size > 2:
                assert np.max(np.abs(np.diff(x, 2))) * RATE**2 <= lim.max_accel_deg_s2 * (1 + 1e-6)
        assert cmd[0, k] == pytest.approx(lim.park_angle_deg) and cmd[-1, k] == pytest.approx(
            lim.park_angle_deg
        )
        if written:
            assert stopped[-1, k] == pytest.approx(lim.park_angle_deg)
