"""Facts about the rig's acquisition loop, shown with tiny fake boards (no simulator, no USB)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.errors import Interrupted, InvalidInput
from protocol_runner.hardware.calibration import CalibrationTable, load_calibration_table
from protocol_runner.hardware.conversions import (
    ai12_code_to_volts,
    angle_to_volts,
    volts_to_ao16_code,
    volts_to_torque,
)
from protocol_runner.hardware.interfaces import AnalogInput, AnalogOutput, Clock, ScanBlock
from protocol_runner.hardware.joint import JointConfig, TrialRecording
from protocol_runner.hardware.rig import Rig
from protocol_runner.hardware.safety import SafetyLimits, SafetyViolation
from tests.rsst_reference import RSST_JOINTS, volts_to_ai12_code

SHIPPED = Path(__file__).resolve().parents[2] / "protocols" / "calibration"
KNEE = RSST_JOINTS[9]
LIMITS = SafetyLimits(
    range_deg=(0.0, 130.0),
    max_rate_deg_s=200.0,
    max_accel_deg_s2=2000.0,
    park_angle_deg=20.0,
    park_rate_deg_s=20.0,
)
TORQUE_VOLTS = 2.5  # what the fake torque sensor always reads


class FakeClock:
    """Simulated time; `late_s` makes every sleep overshoot, like a busy OS."""

    def __init__(self, late_s: float = 0.0) -> None:
        self.t = 1000.0
        self.late_s = late_s

    def now_s(self) -> float:
        return self.t

    def sleep_until(self, t_s: float) -> None:
        if t_s > self.t:
            self.t = t_s + self.late_s


class RecordingAO:
    """Records every call; converts volts to codes like a USB-3105; can fail on a given write."""

    def __init__(self, clock: FakeClock, fail_at_write: int | None = None) -> None:
        self.clock = clock
        self.configured: list[int] = []
        self.writes: list[tuple[float, int, float]] = []
        self.fail_at_write = fail_at_write
        self.volts_now = 0.0

    def configure_channel(self, channel: int) -> None:
        self.configured.append(channel)
        self.volts_now = 0.0

    def write_volts(self, channel: int, volts: float) -> int:
        if self.fail_at_write is not None and len(self.writes) == self.fail_at_write:
            raise OSError(19, "No such device")
        self.writes.append((self.clock.now_s(), channel, volts))
        self.volts_now = volts
        return int(volts_to_ao16_code(volts))

    def volts_at(self, t_s: np.ndarray) -> np.ndarray:
        """The output voltage at each time: the last write at or before it (0 V before any)."""
        times = np.array([w[0] for w in self.writes])
        values = np.array([0.0] + [w[2] for w in self.writes])
        return values[np.searchsorted(times, t_s, side="right")]

    def write_volts_sync(self, volts_by_channel: Mapping[int, float]) -> dict[int, int]:
        return {ch: self.write_volts(ch, v) for ch, v in volts_by_channel.items()}

    def close(self) -> None:
        pass


class EchoAI:
    """12-bit ±10 V scan whose angle channel reads back the volts the AO is commanding (a perfect robot
    with a perfect sensor) and whose torque channel reads a constant."""

    def __init__(self, clock: FakeClock, ao: RecordingAO) -> None:
        self.clock = clock
        self.ao = ao
        self.started: list[tuple[tuple[int, ...], float]] = []
        self.stops = 0
        self._t_start = 0.0
        self._rate = 0.0
        self._next_row = 0
        self._running = False

    @property
    def resolution_bits(self) -> int:
        return 12

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        self.started.append((tuple(channels), rate_hz))
        self._t_start = self.clock.now_s()
        self._rate = rate_hz
        self._next_row = 0
        self._running = True

    def _rows_until_now(self) -> ScanBlock:
        last = int(np.floor((self.clock.now_s() - self._t_start) * self._rate + 1e-9))
        n = max(0, last + 1 - self._next_row)
        t = self._t_start + (self._next_row + np.arange(n)) / self._rate
        self._next_row += n
        volts = np.column_stack([self.ao.volts_at(t), np.full(n, TORQUE_VOLTS)])
        codes = volts_to_ai12_code(volts)
        return ScanBlock(t_s=t, codes=codes, volts=ai12_code_to_volts(codes))

    def read_available(self) -> ScanBlock:
        assert self._running
        return self._rows_until_now()

    def stop_scan(self) -> ScanBlock:
        block = self._rows_until_now()
        self._running = False
        self.stops += 1
        return block

    def close(self) -> None:
        pass


def make_joint(**changes: object) -> JointConfig:
    fields: dict[str, object] = {
        "name": "knee",
        "range_deg": KNEE.range_deg,
        "torque_range_nm": KNEE.torque_range_nm,
        "output_channel": 3,
        "angle_input_channel": 8,
        "torque_input_channel": 9,
        "limits": LIMITS,
    }
    fields.update(changes)
    return JointConfig(**fields)  # type: ignore[arg-type]


def make_rig(
    joint: JointConfig | None = None, *, late_s: float = 0.0, fail_at_write: int | None = None
) -> tuple[Rig, RecordingAO, EchoAI, FakeClock]:
    clock = FakeClock(late_s)
    ao = RecordingAO(clock, fail_at_write)
    ai = EchoAI(clock, ao)
    return Rig([joint or make_joint()], ao, ai, clock), ao, ai, clock


def ramp_deg(lo: float, hi: float, n: int) -> np.ndarray:
    return np.linspace(lo, hi, n)


def test_fakes_satisfy_the_interfaces() -> None:
    _, ao, ai, clock = make_rig()
    assert isinstance(ao, AnalogOutput) and isinstance(ai, AnalogInput) and isinstance(clock, Clock)


def test_codes_and_volts_follow_eq1_and_the_usb3105_format() -> None:
    rig, ao, _, _ = make_rig()
    cmd = ramp_deg(10.0, 120.0, 300)
    rec = rig.run_trajectory([cmd], where="t1")[0]
    expected_volts = angle_to_volts(cmd, KNEE.range_deg)
    np.testing.assert_allclose(rec.command_volts, expected_volts)
    np.testing.assert_array_equal(rec.command_codes, volts_to_ao16_code(expected_volts))
    assert [w[1] for w in ao.writes] == [3] * 300
    np.testing.assert_allclose([w[2] for w in ao.writes], expected_volts)
    assert ao.configured == [3]


def test_time_base_of_output_ticks_and_input_rows() -> None:
    rig, ao, ai, _ = make_rig()
    n = 250
    rec = rig.run_trajectory([np.full(n, 40.0)], where="t1")[0]
    assert ai.started == [((8, 9), 1000.0)]
    np.testing.assert_allclose(rec.command_time_s, np.arange(n) / 100.0, atol=1e-9)
    write_times = np.array([w[0] for w in ao.writes]) - rec.t0_s
    np.testing.assert_allclose(write_times, rec.command_time_s, atol=1e-9)
    # The scan runs from t0 until one tick after the last write, at 1 kHz, without gaps or repeats.
    assert rec.input_time_s[0] == pytest.approx(0.0, abs=1e-9)
    assert rec.input_time_s[-1] == pytest.approx(n / 100.0, abs=1e-9)
    np.testing.assert_allclose(np.diff(rec.input_time_s), 1e-3, atol=1e-9)
    assert ai.stops == 1
    np.testing.assert_array_equal(rec.tick_lateness_s, 0.0)


def test_lateness_is_write_time_minus_schedule() -> None:
    rig, _, _, _ = make_rig(late_s=4e-4)
    rec = rig.run_trajectory([np.full(50, 40.0)], where="t1")[0]
    np.testing.assert_allclose(rec.tick_lateness_s[1:], 4e-4, atol=1e-9)


def test_telemetry_goes_through_eq2_eq3() -> None:
    rig, _, _, _ = make_rig()
    cmd = ramp_deg(30.0, 90.0, 200)
    rec = rig.run_trajectory([cmd], where="t1")[0]
    # Each input row sees the command of the last tick written before it.
    tick_of_row = np.minimum(np.floor(rec.input_time_s * 100.0 + 1e-9).astype(int), cmd.size - 1)
    np.testing.assert_allclose(rec.angle_deg, cmd[tick_of_row], atol=130.0 / 4096)
    np.testing.assert_allclose(rec.torque_nm, volts_to_torque(TORQUE_VOLTS, KNEE.torque_range_nm), atol=0.05)
    np.testing.assert_array_equal(rec.angle_volts, ai12_code_to_volts(rec.angle_codes))


def test_calibration_tables_are_applied_on_both_sides() -> None:
    """With the shipped knee tables and an angle table that inverts the command table (what a perfect
    calibration of this echo 'robot' would give), the measured real angle equals the commanded one;
    the torque table maps the shown torque to the real one."""
    command_table = load_calibration_table(SHIPPED / "knee_command.csv")
    torque_table = load_calibration_table(SHIPPED / "knee_torque.csv")
    joint = make_joint(
        command_table=command_table, angle_table=command_table.inverse(), torque_table=torque_table
    )
    rig, _, _, _ = make_rig(joint)
    cmd = ramp_deg(5.0, 125.0, 400)
    rec = rig.run_trajectory([cmd], where="t1")[0]
    np.testing.assert_allclose(rec.command_volts, angle_to_volts(command_table(cmd), KNEE.range_deg))
    assert np.max(np.abs(rec.command_volts - angle_to_volts(cmd, KNEE.range_deg))) > 0.2  # LUT did something
    tick_of_row = np.minimum(np.floor(rec.input_time_s * 100.0 + 1e-9).astype(int), cmd.size - 1)
    np.testing.assert_allclose(rec.angle_deg, cmd[tick_of_row], atol=0.05)
    shown_nm = volts_to_torque(rec.torque_volts, KNEE.torque_range_nm)
    np.testing.assert_allclose(rec.torque_nm, torque_table(shown_nm))


def test_safety_rejection_happens_before_anything_is_sent() -> None:
    rig, ao, ai, _ = make_rig()
    cmd = ramp_deg(40.0, 131.0, 300)
    with pytest.raises(SafetyViolation, match="step-7") as info:
        rig.run_trajectory([cmd], where="step-7")
    assert info.value.limit == "joint angle"
    assert ao.writes == [] and ao.configured == [] and ai.started == []


def test_command_table_pushing_past_10_volts_is_rejected() -> None:
    table = CalibrationTable(np.array([0.0, 130.0]), np.array([5.0, 135.0]), "real_deg", "input_deg")
    rig, ao, _, _ = make_rig(make_joint(command_table=table))
    with pytest.raises(SafetyViolation, match="voltage"):
        rig.run_trajectory([ramp_deg(60.0, 128.0, 200)], where="s")
    assert ao.writes == []


def test_park_ramps_to_the_park_angle_from_the_last_command() -> None:
    rig, ao, _, _ = make_rig()
    rig.run_trajectory([ramp_deg(60.0, 100.0, 100)], where="t1")
    n_before = len(ao.writes)
    rec = rig.park()[0]
    assert rec.command_deg[0] == pytest.approx(100.0)
    assert rec.command_deg[-1] == LIMITS.park_angle_deg
    assert ao.writes[-1][2] == pytest.approx(float(angle_to_volts(LIMITS.park_angle_deg, KNEE.range_deg)))
    assert len(ao.writes) - n_before == rec.n_ticks
    assert rig.last_command_deg[0] == LIMITS.park_angle_deg
    assert np.max(np.abs(np.diff(rec.command_deg))) * 100.0 <= LIMITS.park_rate_deg_s + 1e-9


def test_park_without_a_previous_command_measures_the_angle() -> None:
    """After configure_channel the output is 0 V, i.e. mid-range (65° for the knee)."""
    rig, _, _, _ = make_rig()
    rig.prepare()
    rec = rig.park()[0]
    assert rec.command_deg[0] == pytest.approx(65.0, abs=0.05)
    assert rec.command_deg[-1] == LIMITS.park_angle_deg


def test_prepare_configures_the_channel_once() -> None:
    rig, ao, _, _ = make_rig()
    rig.prepare()
    rig.run_trajectory([np.full(20, 40.0)], where="a")
    rig.run_trajectory([np.full(20, 40.0)], where="b")
    assert ao.configured == [3]


def test_stop_request_stops_the_scan_and_remembers_the_last_write() -> None:
    rig, ao, ai, _ = make_rig()
    polls = {"n": 0}

    def stop_after_three_reads() -> bool:
        polls["n"] += 1
        return polls["n"] >= 3

    cmd = ramp_deg(30.0, 60.0, 500)
    with pytest.raises(Interrupted, match="trial-3"):
        rig.run_trajectory([cmd], where="trial-3", stop_requested=stop_after_three_reads)
    assert len(ao.writes) == 30
    assert ai.stops == 1
    assert rig.last_command_deg[0] == pytest.approx(cmd[29])


def test_board_failure_mid_trial_stops_the_scan_and_propagates() -> None:
    rig, _, ai, _ = make_rig(fail_at_write=42)
    cmd = ramp_deg(30.0, 60.0, 100)
    with pytest.raises(OSError, match="No such device"):
        rig.run_trajectory([cmd], where="t")
    assert ai.stops == 1
    assert rig.last_command_deg[0] == pytest.approx(cmd[41])


def test_recording_is_consistent() -> None:
    rig, _, _, _ = make_rig()
    rec = rig.run_trajectory([np.full(37, 40.0)], where="w")[0]
    assert isinstance(rec, TrialRecording)
    assert rec.where == "w" and rec.n_ticks == 37
    for name in ("command_deg", "command_volts", "command_codes", "tick_lateness_s"):
        assert getattr(rec, name).shape == (37,)
    for name in ("angle_codes", "torque_codes", "angle_volts", "torque_volts", "angle_deg", "torque_nm"):
        assert getattr(rec, name).shape == (rec.n_samples,)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"range_deg": (130.0, 0.0)}, "range_deg"),
        ({"torque_input_channel": 8}, "different input channels"),
        ({"output_channel": -1}, "output_channel"),
        ({"output_rate_hz": 0.0}, "output_rate_hz"),
        ({"range_deg": (10.0, 130.0)}, "safety range"),
    ],
)
def test_joint_config_validation(changes: dict[str, object], message: str) -> None:
    with pytest.raises(InvalidInput, match=message):
        make_joint(**changes)
