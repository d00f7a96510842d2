"""The DAQ simulator behaves like the rig, end to end through `Rig`.

Each test states a physical or contractual fact of the thesis (§2.4.2 lag, Table 3 torque limit, §3.3.1
start-up transition, §2.5 calibration) or of the DAQ interfaces, and would fail if the model were wrong.
"""

from __future__ import annotations

import time
from dataclasses import replace
from functools import cache

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.calibration import CalibrationTable
from protocol_runner.hardware.conversions import volts_to_angle, volts_to_ao16_code
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock
from protocol_runner.hardware.joint import JointConfig
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyLimits
from protocol_runner.hardware.simulator.daq import SimulatedRig, step_seed
from protocol_runner.hardware.simulator.output import SimulatedClock
from protocol_runner.hardware.simulator.params import SimulatorParams
from protocol_runner.hardware.simulator.plant import JointPlant
from tests.rsst_reference import volts_to_ai12_code

from ..knee_device import KNEE_PARAMS, knee_brace
from ..knee_rig import KNEE_PARK_DEG, KNEE_TORQUE_LIMIT_NM, knee_joint_config

PARK_DEG = KNEE_PARK_DEG
OUTPUT_RATE_HZ = 100.0
INPUT_RATE_HZ = 1000.0


def knee_joint(**tables: CalibrationTable | None) -> JointConfig:
    """The knee (RSST joint 9): Eq 1 range 0-130°, ±84.8 N·m, park at 20°, generous rate limits."""
    return knee_joint_config(
        max_rate_deg_s=100_000.0,
        max_accel_deg_s2=1e9,
        output_rate_hz=OUTPUT_RATE_HZ,
        input_rate_hz=INPUT_RATE_HZ,
        **tables,
    )


@pytest.fixture
def knee() -> JointConfig:
    return knee_joint()


def hold(angle_deg: float, duration_s: float) -> np.ndarray:
    """A constant command: a step from the park angle to `angle_deg` (thesis Appendix A calibration)."""
    return np.full(round(duration_s * OUTPUT_RATE_HZ), float(angle_deg))


def run(sim: SimulatedRig, rig: Rig, command_deg: np.ndarray, step_id: str = "step") -> tuple:
    sim.begin_step(step_id)
    rec = rig.run_trajectory([command_deg], where=step_id)[0]
    return rec.input_time_s, rec.angle_deg, rec.torque_nm, rec


def test_simulated_boards_satisfy_the_daq_interfaces(knee: JointConfig) -> None:
    sim = SimulatedRig([knee], params=KNEE_PARAMS)
    assert isinstance(sim.clock, Clock)
    assert isinstance(sim.ao, AnalogOutput)
    assert isinstance(sim.ai, AnalogInput)
    assert sim.ai.resolution_bits == 12
    assert isinstance(sim.make_rig(), Rig)


def test_step_response_is_a_first_order_lag_of_0_2_s(knee: JointConfig) -> None:
    """Thesis §2.4.2: the joint follows a step as a first-order lag with a 0.2 s time constant. The 45°
    calibration step (Appendix A) from the 20° park angle, brace off: the 63 % time is 0.2 ± 0.05 s and the
    joint settles at the command."""
    sim = SimulatedRig([knee], seed=3, params=KNEE_PARAMS)
    t, angle, _, _ = run(sim, sim.make_rig(), hold(PARK_DEG + 45.0, 2.0))
    reached = np.flatnonzero(angle >= PARK_DEG + 0.632 * 45.0)
    t63 = t[reached[0]]
    assert 0.15 <= t63 <= 0.25
    assert abs(np.mean(angle[t > 1.5]) - (PARK_DEG + 45.0)) < 0.5
    # first order, not a ramp: a quarter of the way is reached in well under a quarter of 4 t63
    t25 = t[np.flatnonzero(angle >= PARK_DEG + 0.25 * 45.0)[0]]
    assert t25 < 0.5 * t63


def test_joint_stalls_where_the_load_reaches_the_torque_limit(knee: JointConfig) -> None:
    """Thesis §5: "when the torque applied to the robot is greater than [±84.8 N·m] the robot cannot move
    past that point". The stiffest springs at the most preload load the joint beyond the limit well before
    130°: commanded to 130° it stops short and the load cell reads the limit; without the brace the same
    command is reached."""
    sim = SimulatedRig([knee], seed=4, params=KNEE_PARAMS)
    rig = sim.make_rig()
    sim.set_device(knee_brace((0.0, 130.0), 6.25, 20.0, 1))
    t, angle, torque, _ = run(sim, rig, hold(130.0, 4.0), "stall")
    late = t > 3.0
    assert np.max(angle) < 100.0
    assert np.ptp(angle[late]) < 1.0  # stopped, not creeping on
    assert abs(np.mean(torque[late]) - KNEE_TORQUE_LIMIT_NM) < 1.5
    assert sim.plant().load_nm <= KNEE_TORQUE_LIMIT_NM * 1.01  # the actuator never holds more than its limit

    sim.set_device(None)
    t, angle, torque, _ = run(sim, rig, hold(130.0, 4.0), "free")
    assert abs(np.mean(angle[t > 3.0]) - 130.0) < 1.0
    assert np.mean(torque[t > 3.0]) < 0.6 * KNEE_TORQUE_LIMIT_NM


def test_start_up_transition_emerges_from_the_lag(knee: JointConfig) -> None:
    """Thesis §3.3.1: each trial starts with the leg at its park position while the trajectory starts
    elsewhere, so the recording begins with a transition before the joint follows the command."""
    sim = SimulatedRig([knee], seed=5, params=KNEE_PARAMS)
    p = 2.0 * np.pi * 65.0 / 50.0
    tk = np.arange(round(1.5 * p * OUTPUT_RATE_HZ)) / OUTPUT_RATE_HZ
    command = 65.0 + 65.0 * np.sin(2.0 * np.pi * tk / p)  # starts at 65°, the leg is at 20°
    t, angle, _, rec = run(sim, sim.make_rig(), command, "transition")
    assert abs(np.mean(angle[:5]) - PARK_DEG) < 1.0
    cmd_at_input = np.interp(t, rec.command_time_s, rec.command_deg)
    gap = np.abs(cmd_at_input - angle)
    assert gap[t < 0.1].min() > 20.0  # far from the trajectory at first
    assert np.max(gap[(t > 2.0) & (t < p)]) < 15.0  # then it follows, a lag behind


def test_same_seed_and_step_give_identical_data_another_step_other_noise(knee: JointConfig) -> None:
    """Every random draw comes from a generator seeded by (session seed, step id), so a resumed
    session reproduces an uninterrupted one bit for bit."""
    command = hold(60.0, 1.0)
    sim_a = SimulatedRig([knee], seed=11, params=KNEE_PARAMS)
    rig_a = sim_a.make_rig()
    _, _, _, first = run(sim_a, rig_a, command, "set1/trial1")
    _, _, _, other_step = run(sim_a, rig_a, command, "set1/trial2")
    sim_b = SimulatedRig(
        [knee], seed=11, params=KNEE_PARAMS
    )  # a fresh process, after unrelated work in another step
    _, _, _, _ = run(sim_b, sim_b.make_rig(), hold(90.0, 0.5), "set0/warm-up")
    _, _, _, again = run(sim_b, sim_b.make_rig(), command, "set1/trial1")
    other_seed = run(
        SimulatedRig([knee], seed=12, params=KNEE_PARAMS),
        SimulatedRig([knee], seed=12, params=KNEE_PARAMS).make_rig(),
        command,
        "x",
    )[3]

    assert np.array_equal(first.angle_codes, again.angle_codes)
    assert np.array_equal(first.torque_codes, again.torque_codes)
    assert not np.array_equal(first.torque_codes, other_step.torque_codes)
    assert not np.array_equal(first.torque_codes, other_seed.torque_codes)
    # other noise, same physics
    assert np.max(np.abs(first.angle_deg - other_step.angle_deg)) < 1.5
    assert step_seed(11, "set1/trial1") == step_seed(11, "set1/trial1") != step_seed(11, "set1/trial2")


def test_data_do_not_depend_on_how_long_the_session_has_run(knee: JointConfig) -> None:
    """A resumed session's clock starts afresh while the uninterrupted one has run for hours: the step's
    data must not depend on the clock's absolute value (float rounding of write and row times)."""
    command = 65.0 + 40.0 * np.sin(np.arange(300) / 30.0)
    fresh = SimulatedRig([knee], seed=13, params=KNEE_PARAMS)
    _, _, _, a = run(fresh, fresh.make_rig(), command, "k4/on/2")
    late = SimulatedRig([knee], seed=13, params=KNEE_PARAMS)
    late.clock.sleep_until(3 * 3600.0 + 0.123456789)
    _, _, _, b = run(late, late.make_rig(), command, "k4/on/2")
    assert np.array_equal(a.angle_codes, b.angle_codes)
    assert np.array_equal(a.torque_codes, b.torque_codes)


def test_data_do_not_depend_on_how_often_the_scan_is_read(knee: JointConfig) -> None:
    """The plant integrates lazily on a fixed grid: reading the scan every millisecond with every row
    handed over as soon as it is due (as in real time), or in the simulated board's 1 s transfers read
    every millisecond or once a second, yields the same rows (so a realtime or a differently paced loop
    sees the same rig)."""

    def acquire(read_every_s: float, transfer_s: float) -> tuple[np.ndarray, int]:
        sim = SimulatedRig([knee], seed=21, params=KNEE_PARAMS)
        sim.ai.transfer_s = transfer_s
        sim.begin_step("chunks")
        sim.ai.start_scan([8, 20, 3], INPUT_RATE_HZ)
        blocks = []
        for k in range(300):
            sim.ao.write_volts(8, -10.0 + 20.0 * (20.0 + 0.3 * k) / 130.0)
            t_next = (k + 1) / OUTPUT_RATE_HZ
            while sim.clock.now_s() < t_next - 1e-12:
                sim.clock.sleep_until(min(t_next, sim.clock.now_s() + read_every_s))
                blocks.append(sim.ai.read_available().codes)
        blocks.append(sim.ai.stop_scan().codes)
        return np.concatenate(blocks), sum(b.shape[0] > 0 for b in blocks)

    fine, fine_reads = acquire(0.001, 0.0)
    transfers, transfer_reads = acquire(0.001, 1.0)
    coarse, _ = acquire(1.0, 1.0)
    assert fine.shape == transfers.shape == coarse.shape == (3001, 3)
    assert np.array_equal(fine, transfers)
    assert np.array_equal(fine, coarse)
    assert fine_reads == 3000 and transfer_reads == 4  # rows 0-1, then every ms / 3 transfers and the rest
    assert np.ptp(fine[:, 0]) > 100  # the joint moved: not a comparison of constants


def test_the_scan_hands_its_rows_over_in_whole_transfers(knee: JointConfig) -> None:
    """In simulated time the DT9814 stand-in hands over 1 s of rows at a time, as a USB board hands over
    whole packets, and the rest when the scan stops; in real time every row as soon as it is due."""
    sim = SimulatedRig([knee], seed=3, params=KNEE_PARAMS)
    sim.begin_step("transfers")
    sim.ai.start_scan([8, 20], INPUT_RATE_HZ)  # row i at i ms
    sizes = []
    for t_s in (0.5, 1.0, 1.5, 2.3):
        sim.clock.sleep_until(t_s)
        sizes.append(sim.ai.read_available().n_samples)
    last = sim.ai.stop_scan()
    assert sizes == [0, 1000, 0, 1000]
    assert last.n_samples == 301 and last.t_s[-1] == pytest.approx(2.3)
    assert SimulatedRig([knee], realtime=True).ai.transfer_s == 0.0


def test_a_dry_run_is_the_rigs_paced_loop_in_simulated_time(knee: JointConfig) -> None:
    """The rig drives the simulated boards through its own paced loop: one USB-3105 write per sample at
    its scheduled time (the simulated clock jumps there, so no tick is late), every row of the scan
    recorded, the clock one tick past the last write at the end."""
    sim = SimulatedRig([knee], seed=5, params=KNEE_PARAMS)
    rig = sim.make_rig()
    sim.clock.sleep_until(sim.clock.now_s() + 7.25)
    command = 65.0 + 40.0 * np.sin(np.arange(450) / 30.0)
    _, _, _, rec = run(sim, rig, command, "paced")
    t, channel, code = sim.ao.records()
    writes = channel == knee.output_channel
    schedule = rec.t0_s + np.arange(451) * (1.0 / OUTPUT_RATE_HZ)
    np.testing.assert_array_equal(t[writes][1:], schedule[:450])  # after the channel's set-up
    np.testing.assert_array_equal(code[writes][1:], rec.command_codes)
    assert np.all(rec.tick_lateness_s == 0.0)
    assert rec.n_samples == 4501  # 4.5 s at 1 kHz, both ends included
    assert sim.clock.now_s() == schedule[450]


def test_brace_on_and_brace_off_trials_differ(knee: JointConfig) -> None:
    """The brace's springs and brake add torque that resists flexion (thesis §5, Figure 36): with the
    medium spring fitted the joint needs clearly more torque at 90° than the bare robot."""
    sim = SimulatedRig([knee], seed=6, params=KNEE_PARAMS)
    rig = sim.make_rig()
    _, _, torque_off, _ = run(sim, rig, hold(90.0, 2.0), "off")
    sim.set_device(knee_brace((0.0, 130.0), 3.75, 13.0))
    _, _, torque_on, _ = run(sim, rig, hold(90.0, 2.0), "on")
    # K2 at the centre preload pulls ~35 N·m at 90° (Eq 13-18), plus the brake
    assert np.mean(torque_on[-500:]) - np.mean(torque_off[-500:]) > 25.0


def test_calibration_tables_make_measured_match_real() -> None:
    """Thesis §2.5: the robot has its own nonlinearity and the rig's look-up tables undo it. The simulated
    robot's nonlinearity is the inverse of the protocol's tables, so after the rig's tables the measured
    angle and torque match the real (plant) values, while the raw Eq 2 angle does not."""
    real = np.linspace(0.0, 130.0, 14)
    bend = real + 4.0 * np.sin(np.pi * real / 130.0)
    command_table = CalibrationTable(real, bend, "real_deg", "input_deg")  # real -> what to command
    angle_table = CalibrationTable(bend, real, "output_deg", "real_deg")  # shown -> real
    torque_out = np.linspace(-84.8, 84.8, 9)
    torque_table = CalibrationTable(torque_out, 0.95 * torque_out, "output_nm", "real_nm")
    joint = knee_joint(command_table=command_table, angle_table=angle_table, torque_table=torque_table)
    quiet = replace(KNEE_PARAMS, angle_noise_deg=0.0, torque_noise_nm=0.0)
    sim = SimulatedRig([joint], seed=1, params=quiet)
    _, angle, torque, rec = run(sim, sim.make_rig(), hold(65.0, 2.0), "lut")
    assert abs(sim.plant().angle_deg - 65.0) < 0.3  # the robot went where the table asked
    assert abs(angle[-1] - sim.plant().angle_deg) < 0.1  # 12-bit LSB is 0.032°
    assert abs(torque[-1] - sim.plant().load_nm) < 0.1
    raw_eq2 = float(volts_to_angle(rec.angle_volts[-1], joint.range_deg))
    assert abs(raw_eq2 - angle[-1]) > 3.0  # the sensor's own nonlinearity is really there


def test_analog_output_quantises_like_a_usb_3105(knee: JointConfig) -> None:
    sim = SimulatedRig([knee], params=KNEE_PARAMS)
    assert sim.ao.write_volts(8, 0.0) == 32768
    assert sim.ao.write_volts(8, 10.0) == 65535  # full scale is +9.99969 V
    assert sim.ao.write_volts(8, -12.0) == 0  # clamped
    sim.ao.configure_channel(3)  # also drives the output to 0 V
    assert sim.ao.write_volts_sync({1: 1.0, 2: -1.0}) == {1: 36045, 2: 29491}
    t, channel, code = sim.ao.records()
    assert np.all(t == sim.clock.now_s())  # stamped with the clock (simulated time stood still)
    assert channel.tolist() == [8, 8, 8, 3, 1, 2]
    assert code.tolist() == [32768, 65535, 0, 32768, 36045, 29491]
    with pytest.raises(InvalidInput, match="channel"):
        sim.ao.write_volts(16, 0.0)


def test_analog_input_gives_12_bit_twos_complement_codes(knee: JointConfig) -> None:
    """DT9814: V = 20 code / 4096, codes -2048..2047; unconnected channels read about 0 V."""
    sim = SimulatedRig([knee], seed=2, params=KNEE_PARAMS)
    sim.begin_step("codes")
    sim.ai.start_scan([8, 20, 0], INPUT_RATE_HZ)
    sim.clock.sleep_until(sim.clock.now_s() + 0.5)
    block = sim.ai.stop_scan()
    assert block.n_samples == 501  # the first row at the start, then one per millisecond, ends included
    assert block.codes.dtype == np.int32
    assert block.codes.min() >= -2048 and block.codes.max() <= 2047
    assert np.allclose(block.volts, 20.0 * block.codes / 4096.0)
    park_volts = -10.0 + 20.0 * PARK_DEG / 130.0
    assert abs(np.mean(block.volts[:, 0]) - park_volts) < 0.02
    assert np.max(np.abs(block.volts[:, 2])) < 0.05
    with pytest.raises(InvalidInput):
        sim.ai.start_scan([24], INPUT_RATE_HZ)


def test_simulated_clock_jumps_and_realtime_clock_sleeps() -> None:
    clock = SimulatedClock()
    wall = time.monotonic()
    clock.sleep_until(3600.0)
    assert clock.now_s() == 3600.0
    assert time.monotonic() - wall < 1.0  # an hour of simulated time, no sleeping
    clock.sleep_until(10.0)
    assert clock.now_s() == 3600.0  # never goes back

    real = SimulatedClock(realtime=True)
    target = real.now_s() + 0.02
    real.sleep_until(target)
    assert real.now_s() >= target


def test_set_device_rejects_impossible_elements_naming_the_parameter(knee: JointConfig) -> None:
    sim = SimulatedRig([knee], params=KNEE_PARAMS)
    with pytest.raises(InvalidInput, match=r"'stops'.*'range_deg'"):
        sim.set_device(knee_brace((90.0, 40.0), 0.0, 0.0))
    with pytest.raises(InvalidInput, match=r"'brake'.*'torque_nm'"):
        sim.set_device(knee_brace((0.0, 130.0), -1.0, 0.0))
    with pytest.raises(InvalidInput, match="preload_index"):
        sim.set_device(knee_brace((0.0, 130.0), 0.0, 13.0, preload_index=2.5))  # type: ignore[arg-type]
    two_stops = [
        *knee_brace((0.0, 130.0), 0.0, 0.0),
        ("more", "rom_stops", {"range_deg": [0, 1], "stop_stiffness_nm_per_deg": 1}),
    ]
    with pytest.raises(InvalidInput, match="one rom_stops"):
        sim.set_device(two_stops)
    assert sim.device() is None
    with pytest.raises(InvalidInput, match="lag_time_constant_s"):
        SimulatorParams(lag_time_constant_s=0.0)


def test_bare_robot_shows_its_own_hysteresis(knee: JointConfig) -> None:
    """Thesis §5: "all graphs show hysteresis of the joint. This is an artifact of the robot": brace off,
    a sinusoid's torque is higher while flexing than while extending at the same angle, so the loop
    encloses positive energy."""
    sim = SimulatedRig([knee], seed=8, params=KNEE_PARAMS)
    p = 2.0 * np.pi * 45.0 / 50.0
    tk = np.arange(round(3 * p * OUTPUT_RATE_HZ)) / OUTPUT_RATE_HZ
    t, angle, torque, _ = run(sim, sim.make_rig(), 65.0 + 45.0 * np.sin(2.0 * np.pi * tk / p), "bare")
    cycle = (t >= p) & (t < 2 * p)
    a, tq = angle[cycle], torque[cycle]
    energy_j = float(np.sum(0.5 * (tq[1:] + tq[:-1]) * np.diff(a))) * np.pi / 180.0
    # Coulomb friction F over a travel s dissipates about 2·F·s per cycle; the model's robot has F = 2.5 N·m
    travel_rad = np.radians(np.ptp(a))
    assert energy_j > 2.0 * 2.0 * travel_rad


def test_docs_list_every_parameter_with_its_value() -> None:
    """docs/simulator.md carries the parameter table; it must not drift from params.py."""
    from dataclasses import fields
    from pathlib import Path

    doc = (Path(__file__).resolve().parents[2] / "docs" / "simulator.md").read_text(encoding="utf-8")
    rows = {
        line.split("|")[1].strip().strip("`"): line for line in doc.splitlines() if line.startswith("| `")
    }
    defaults = SimulatorParams()
    for f in fields(SimulatorParams):
        assert f.name in rows, f"docs/simulator.md lacks {f.name}"
        assert format(getattr(defaults, f.name), "g") in rows[f.name], f"{f.name}: value differs in the docs"


@cache
def _ao_sim() -> SimulatedRig:
    return SimulatedRig([knee_joint()], params=KNEE_PARAMS)


@settings(max_examples=300, deadline=None)
@given(st.floats(min_value=-12.0, max_value=12.0, allow_nan=False))
def test_output_codes_follow_the_conversion_module(volts: float) -> None:
    """The simulated USB-3105 sends exactly the code of `conversions.volts_to_ao16_code`."""
    assert _ao_sim().ao.write_volts(0, volts) == int(volts_to_ao16_code(volts))


def test_unloaded_joint_is_exactly_a_first_order_lag() -> None:
    """With no load (no gravity, no friction) the servo law reduces to dθ/dt = (θ_cmd − θ)/τ: the
    response to a step is θ_cmd − Δ·exp(−t/τ) (explicit Euler on the 0.5 ms grid: within 0.1°)."""
    params = SimulatorParams(gravity_torque_max_nm=0.0, robot_friction_nm=0.0, robot_viscous_nm_per_deg_s=0.0)
    plant = JointPlant(params, (0.0, 130.0), (-84.8, 84.8))
    plant.reset(20.0)
    plant.push_command(0, 80.0)
    steps = np.arange(0, 2001, 10, dtype=np.int64)  # 0 .. 1 s
    angle, torque = plant.advance(2000, steps)
    t = steps * params.plant_step_s
    expected = 80.0 - 60.0 * np.exp(-t / params.lag_time_constant_s)
    assert np.max(np.abs(angle - expected)) < 0.1
    assert np.all(torque == 0.0)


def test_torque_limit_comes_from_the_joint_not_from_the_knee() -> None:
    """Nothing may assume the knee: an elbow (Table 3: -39.6..31 N·m) carrying the default
    shank weight cannot lift it to 90°; it stalls where gravity + friction reach its own 31 N·m."""
    elbow = JointConfig(
        name="elbow",
        range_deg=(0.0, 130.0),
        torque_range_nm=(-39.6, 31.0),
        output_channel=4,
        angle_input_channel=4,
        torque_input_channel=16,
        limits=SafetyLimits(
            range_deg=(0.0, 130.0),
            max_rate_deg_s=100_000.0,
            max_accel_deg_s2=1e9,
            park_angle_deg=10.0,
            park_rate_deg_s=30.0,
        ),
    )
    sim = SimulatedRig([elbow], seed=9, params=KNEE_PARAMS)
    t, angle, torque, _ = run(sim, sim.make_rig(), hold(90.0, 4.0), "elbow")
    late = t > 3.0
    assert np.mean(angle[late]) < 70.0
    assert abs(np.mean(torque[late]) - 31.0) < 1.0


def test_realtime_clock_paces_a_short_trial(knee: JointConfig) -> None:
    """`--realtime`: the same run, paced by the wall clock (a 0.2 s trial takes at least 0.2 s)."""
    sim = SimulatedRig([knee], seed=10, realtime=True, params=KNEE_PARAMS)
    rig = sim.make_rig()
    sim.begin_step("rt")
    wall = time.monotonic()
    rec = rig.run_trajectory([hold(25.0, 0.2)], where="rt")[0]
    assert time.monotonic() - wall >= 0.2
    assert rec.n_samples >= 200
    assert abs(rec.angle_deg[0] - PARK_DEG) < 1.0


_DIGEST_SCRIPT = """
import hashlib, sys
import numpy as np
sys.path.insert(0, sys.argv[1])
from tests.hardware.test_simulator import KNEE_PARAMS, hold, knee_joint, run
from protocol_runner.hardware.simulator.daq import SimulatedRig
sim = SimulatedRig([knee_joint()], seed=5, params=KNEE_PARAMS)
rec = run(sim, sim.make_rig(), hold(50.0, 0.3), "set2/trial3")[3]
print(hashlib.sha256(rec.angle_codes.tobytes() + rec.torque_codes.tobytes()).hexdigest())
"""


def test_data_are_reproducible_in_another_process() -> None:
    """A resumed session runs in a new process (another PYTHONHASHSEED): its data must be identical."""
    import hashlib
    import os
    import subprocess
    import sys
    from pathlib import Path

    sim = SimulatedRig([knee_joint()], seed=5, params=KNEE_PARAMS)
    rec = run(sim, sim.make_rig(), hold(50.0, 0.3), "set2/trial3")[3]
    here = hashlib.sha256(rec.angle_codes.tobytes() + rec.torque_codes.tobytes()).hexdigest()
    env = dict(os.environ, PYTHONHASHSEED="12345")
    out = subprocess.run(
        [sys.executable, "-c", _DIGEST_SCRIPT, str(Path(__file__).resolve().parents[2])],
        capture_output=True,
        text=True,
        env=env,
        check=True,
        timeout=120,
    )
    assert out.stdout.strip() == here


def _plant(device: list | None) -> JointPlant:
    plant = JointPlant(KNEE_PARAMS, (0.0, 130.0), (-84.8, 84.8))
    plant.set_device(device)
    return plant


def test_brace_springs_are_the_physical_model_of_eq_13_18() -> None:
    """The brace's spring torque in the plant is `models.spring.spring_torque_nm` (thesis Eq 13-18)."""
    from protocol_runner.models.spring import spring_torque_nm

    from ..knee_device import KNEE_GEOMETRY, KNEE_MAX_PRELOAD_MM

    bare = _plant(None)
    for k, n in ((4.4, 1), (13.0, 3), (20.0, 5)):
        braced = _plant(knee_brace((0.0, 130.0), 0.0, k, n, cuff_shift=False))
        for angle in (5.0, 47.3, 90.0, 118.0):
            spring = braced.load_at_nm(angle) - bare.load_at_nm(angle)
            expected = spring_torque_nm(
                angle, k, n, max_preload_mm=KNEE_MAX_PRELOAD_MM, geometry=KNEE_GEOMETRY
            )
            assert spring == pytest.approx(float(expected), abs=0.01)


def test_low_angle_bump_grows_with_speed_and_shrinks_with_spring_force() -> None:
    """Thesis §5.1/§5.4/§5.5: the brace's instability near 40° is enhanced by speed and reduced by stiffer
    springs or more preload. Away from it, speed only adds the robot's viscous torque."""

    def bump(brace: list, angle: float, speed: float) -> float:
        plant, bare = _plant(brace), _plant(None)
        return (plant.load_at_nm(angle, speed) - plant.load_at_nm(angle)) - (
            bare.load_at_nm(angle, speed) - bare.load_at_nm(angle)
        )

    def setup(k: float, n: int = 3) -> list:
        return knee_brace((0.0, 130.0), 0.0, k, n)

    assert bump(setup(0.0), 35.0, 50.0) > bump(setup(0.0), 35.0, 25.0) > 0.5
    assert bump(setup(0.0), 35.0, 50.0) > bump(setup(4.4), 35.0, 50.0) > bump(setup(13.0), 35.0, 50.0)
    assert bump(setup(13.0), 35.0, 50.0) > bump(setup(20.0), 35.0, 50.0)
    assert bump(setup(13.0, n=5), 35.0, 50.0) > bump(setup(13.0, n=1), 35.0, 50.0)  # 1 = most preload
    assert abs(bump(setup(0.0), 80.0, 50.0)) < 1e-3


def test_fused_scan_kernel_quantises_like_the_dt9814_conversions() -> None:
    """One scan read runs integration, sensor chain and ADC in a single kernel (`JointPlant.scan`); its
    codes, volts and row times must be exactly the step-by-step path's: the plant's angle and torque on
    each row's grid step through the tabulated sensor chain plus noise, then the DT9814's
    `volts_to_ai12_code` / `ai12_code_to_volts`, rows at t0 + i / rate (DT9814, §2.3)."""
    from protocol_runner.hardware.conversions import (
        AI12_MAX_CODE,
        AI12_MIN_CODE,
        AI12_VOLTS_PER_CODE,
        ai12_code_to_volts,
    )

    plants = []
    for _ in range(2):
        plant = JointPlant(KNEE_PARAMS, (0.0, 130.0), (-84.8, 84.8))
        plant.set_device(knee_brace((0.0, 130.0), 3.75, 13.0))
        plant.reset(20.0)
        for k in range(0, 4000, 20):  # a 100 Hz ramp 20 -> 120 deg, held beyond the joint's range
            plant.push_command(k, 20.0 + 0.05 * k)
        plants.append(plant)
    roles = np.array([1, 2, 0], dtype=np.int64)  # angle, torque, an idle channel
    scales = np.array([0.01, 0.02, 0.005])
    knots = np.array([-1e6, 1e6])
    sensors = (roles, scales, knots, knots * 20.0 / 130.0, knots, knots * 10.0 / 84.8)
    noise = np.random.default_rng(3).standard_normal(3 * 1500) * 3.0
    t0, origin, rate = 0.25, 0.0, 1000.0
    row_t = t0 + np.arange(7, 7 + 1500, dtype=np.float64) / rate
    steps = np.maximum(np.floor((row_t - origin) / KNEE_PARAMS.plant_step_s + 1e-6), 0).astype(np.int64)
    angle, torque = plants[0].advance(3000, steps)
    n = angle.shape[0]
    chain = np.column_stack([np.interp(angle, knots, sensors[3]), np.interp(torque, knots, sensors[5])])
    raw = noise[: 3 * n].reshape(n, 3) * scales
    raw[:, :2] += chain
    t_s, codes, volts, any_nan = plants[1].scan(
        3000, (t0, origin, rate, 7, 1500), sensors, noise, (AI12_VOLTS_PER_CODE, AI12_MIN_CODE, AI12_MAX_CODE)
    )
    assert not any_nan
    assert raw.shape == codes.shape == volts.shape and 0 < n < 1500  # only rows reached
    assert np.array_equal(codes, volts_to_ai12_code(raw)) and codes.dtype == np.int32
    assert np.array_equal(volts, ai12_code_to_volts(codes))
    assert np.array_equal(t_s, row_t[:n])
    assert np.ptp(codes[:, 0]) > 100  # the joint really moved: not a comparison of constants


def test_scan_noise_is_the_step_stream_in_order_whatever_the_block_sizes(knee: JointConfig) -> None:
    """The noise the scans consume is the step generator's standard normals in draw order: blocks of any
    size, partly consumed (rows not yet due), read into a reused array, give the numbers one draw gives."""
    from protocol_runner.hardware.simulator.daq import NOISE_BLOCK, step_seed

    model = SimulatedRig([knee], seed=11, params=KNEE_PARAMS).models[0]
    model.begin_step("set1/trial1")
    pick = np.random.default_rng(0)
    consumed = []
    for _ in range(400):
        count = int(pick.integers(0, 3 * NOISE_BLOCK))
        used = int(pick.integers(0, count + 1))
        consumed.append(model._noise(count)[:used].copy())
        model._noise_pos += used  # as a scan that reached `used` of the values
    stream = np.concatenate(consumed)
    expected = np.random.default_rng(step_seed(11, "set1/trial1")).standard_normal(stream.size)
    assert stream.size > 10 * NOISE_BLOCK
    assert np.array_equal(stream, expected)
