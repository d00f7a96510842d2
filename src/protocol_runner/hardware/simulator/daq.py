"""The DAQ simulator: a clock, an analog output and an analog input scan that satisfy
`hardware.interfaces` and drive a physical model of each joint of the rig (`plant.py`) instead of the RSST.

Signal path, mirroring the real rig (thesis §2.4-2.5), per joint:

    Rig ── volts ──▶ SimulatedAnalogOutput: USB-3105 16-bit code, recorded with its time
        ──▶ the robot's VME reads the code's volts ──▶ Eq 2 (the inverse of Eq 1) over the joint range
        ──▶ the robot's own nonlinearity (the inverse of the protocol's command table, thesis §2.5.1)
        ──▶ JointPlant (servo + loads), integrated lazily up to the clock when the scan is read
        ──▶ real angle / load torque ──▶ the robot's sensor nonlinearity (inverses of the angle and torque
            tables) ──▶ Eq 1 / Eq 3 inverted ──▶ volts + noise ──▶ DT9814 12-bit ±10 V codes at the scan rate

so that, after the rig applies its calibration tables, measured ≈ real. With no table the robot is linear.

Several joints share one clock, one USB-3105 stand-in and one scan, and are simulated independently: each
plant acts only on its own channel's writes, at their time, and sees only its own device.

Determinism (docs/simulator.md, "Determinism"): `SimulatedRig.begin_step(step_id, trial)` reseeds each
joint's noise from sha256(joint seed, step id), draws the trial's friction spread from sha256(joint seed,
trial), rests the joint at its park angle and restarts the plant's grid at the clock. The joint seed is the
session seed on a rig of one joint, `joint_seed` of (session seed, joint name) on a rig of several. Fixed
grid, commands from the first grid step at or after their write, noise drawn row by row: the same seed and
step id give identical arrays however often the scan is read (in simulated time; `realtime=True` paces with
the wall clock and its write times jitter).
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput
from protocol_runner.hardware.conversions import (
    AI12_MAX_CODE,
    AI12_MIN_CODE,
    AI12_VOLTS_PER_CODE,
    angle_to_volts,
    ao16_code_to_volts,
    torque_to_volts,
    volts_to_angle,
)
from protocol_runner.hardware.interfaces import ScanBlock
from protocol_runner.hardware.simulator.device import ComposedDevice
from protocol_runner.hardware.simulator.kernels import GRID_TOL, ROLE_ANGLE, ROLE_TORQUE
from protocol_runner.hardware.simulator.output import SimulatedAnalogOutput, SimulatedClock, check_channel
from protocol_runner.hardware.simulator.params import DEFAULT_PARAMS, SimulatorParams, trial_factors
from protocol_runner.hardware.simulator.plant import JointPlant

if TYPE_CHECKING:
    from protocol_runner.hardware.calibration import CalibrationTable
    from protocol_runner.hardware.joint import JointConfig
    from protocol_runner.hardware.rig import Rig

FloatArray = npt.NDArray[np.float64]


_AI12 = (AI12_VOLTS_PER_CODE, AI12_MIN_CODE, AI12_MAX_CODE)
"""The DT9814's 12-bit ±10 V two's-complement quantisation, as `kernels.scan_rows` applies it."""

AI_CHANNELS = 24
"""DT9814-10V: 24 analog inputs (thesis §2.3)."""
AI_MAX_RATE_HZ = 50_000.0
"""DT9814 maximum aggregate rate (thesis §2.3)."""
TRANSFER_S = 1.0
"""In simulated time the board hands its rows over in transfers of this much scan time, as a USB board
hands over whole packets: a read before a transfer is complete returns no rows, `stop_scan` returns the
rest. The rows do not depend on it (the plant is integrated on a fixed grid whatever the reads); it sets
how many compiled calls a dry run makes: one per second of scan instead of one per read of the rig's loop
(every 100 ms). In real time (`--realtime`) every row is handed over as soon as it is due
(`SimulatedAnalogInput.transfer_s` = 0)."""
NOISE_BLOCK = 8192
"""Standard normals drawn from the step's generator at a time; rows consume them in order, so the values a
row gets do not depend on how the scan is read."""


def step_seed(seed: int, step_id: str) -> int:
    """The 128-bit seed of one step's noise generator: sha256 of the session seed and the step id
    (stable across processes and Python versions, unlike `hash()`)."""
    digest = hashlib.sha256(f"{int(seed)}\x1f{step_id}".encode()).digest()
    return int.from_bytes(digest[:16], "little")


def joint_seed(seed: int, joint: str) -> int:
    """The seed of one joint's model on a rig of several joints: sha256 of the session seed and the joint's
    name (64 bits)."""
    return int.from_bytes(hashlib.sha256(f"{int(seed)}\x1fjoint\x1f{joint}".encode()).digest()[:8], "little")


def spread_seed(seed: int, trial: str) -> int:
    """The seed of a trial's between-trial spread (`params.trial_factors`): `step_seed` of the session seed
    and the trial's name with a suffix, so that it is not the noise stream of any step."""
    return step_seed(seed, f"{trial}\x1ftrial spread")


class _RigModel:
    """The simulated robot behind the boards: command decoding, the plant, sensors and noise."""

    def __init__(
        self,
        joint: JointConfig,
        params: SimulatorParams,
        seed: int,
        clock: SimulatedClock,
        output: SimulatedAnalogOutput,
    ) -> None:
        self.joint = joint
        self.params = params
        self.seed = int(seed)
        self.clock = clock
        self.range_deg = (float(joint.range_deg[0]), float(joint.range_deg[1]))
        self.torque_range_nm = (float(joint.torque_range_nm[0]), float(joint.torque_range_nm[1]))
        self.plant = JointPlant(params, self.range_deg, self.torque_range_nm)
        self._output = output
        output.listen(self.on_writes)
        self._output_channel = joint.output_channel
        self._inv_dt = 1.0 / params.plant_step_s
        self.channels = (joint.angle_input_channel, joint.torque_input_channel)
        # the robot's own nonlinearities: the inverses of the protocol's calibration tables
        command_nl, angle_nl, torque_nl = (
            None if t is None else t.inverse()
            for t in (joint.command_table, joint.angle_table, joint.torque_table)
        )
        # What the robot does with each of the 65536 output codes: code -> volts (USB-3105) -> Eq 2 over the
        # joint range -> the robot's own nonlinearity (inverse of the command table). Tabulated once, so a
        # write costs a look-up.
        input_deg = volts_to_angle(ao16_code_to_volts(np.arange(65536)), self.range_deg)
        if command_nl is not None:
            input_deg = command_nl(input_deg)
        self.target_by_code = np.ascontiguousarray(input_deg, dtype=np.float64)
        # The sensor chains, real value -> the robot's sensor nonlinearity (inverse of the protocol's output
        # table) -> Eq 1 / Eq 3 inverted -> volts, are piecewise linear: tabulate them on the table's knots
        # (plus two far knots that carry the tables' linear extrapolation) so a read costs one np.interp.
        angle_chain = self._sensor_chain(
            angle_nl, self.range_deg, lambda x: angle_to_volts(x, self.range_deg)
        )
        torque_chain = self._sensor_chain(
            torque_nl, self.torque_range_nm, lambda x: torque_to_volts(x, self.torque_range_nm)
        )
        volts_span = 20.0
        self.angle_noise_v = params.angle_noise_deg * volts_span / (self.range_deg[1] - self.range_deg[0])
        self.torque_noise_v = (
            params.torque_noise_nm * volts_span / (self.torque_range_nm[1] - self.torque_range_nm[0])
        )
        self._sensors = (
            np.zeros(0, dtype=np.int64),
            np.zeros(0, dtype=np.float64),
            *angle_chain,
            *torque_chain,
        )
        self._roles_key: tuple[int, ...] = ()
        self.origin_s = 0.0
        self.step_id = ""
        self.rng = np.random.default_rng(step_seed(self.seed, ""))
        self._noise_buf = np.zeros(0, dtype=np.float64)
        self._noise_pos = 0

    @staticmethod
    def _sensor_chain(
        nonlinearity: CalibrationTable | None,
        span: tuple[float, float],
        to_volts: Callable[[FloatArray], FloatArray],
    ) -> tuple[FloatArray, FloatArray]:
        width = span[1] - span[0]
        far = 1000.0 * width
        if nonlinearity is None:
            knots = np.array([span[0] - far, span[1] + far], dtype=np.float64)
            return knots, to_volts(knots)
        knots = np.concatenate([[nonlinearity.x[0] - far], nonlinearity.x, [nonlinearity.x[-1] + far]])
        return knots, to_volts(nonlinearity(knots))

    def begin_step(self, step_id: str, trial: str | None = None) -> None:
        self.step_id = step_id
        self.rng = np.random.default_rng(step_seed(self.seed, step_id))
        self._noise_buf = np.zeros(0, dtype=np.float64)
        self._noise_pos = 0
        self.origin_s = self.clock.now_s()
        spread = np.random.default_rng(spread_seed(self.seed, step_id if trial is None else trial))
        self.plant.set_trial_factors(trial_factors(self.params, spread))
        self.plant.reset(self.joint.limits.park_angle_deg)

    def on_writes(self, t_s: FloatArray, channel: npt.NDArray[np.int64], code: npt.NDArray[np.int64]) -> None:
        """The output updates written since the robot last looked (`SimulatedAnalogOutput.deliver`): those
        on the joint's channel become commands held from the first grid step at or after their time."""
        mine = channel == self._output_channel
        steps = np.ceil((t_s[mine] - self.origin_s) * self._inv_dt - GRID_TOL).astype(np.int64)
        self.plant.push_commands(steps, self.target_by_code[code[mine]])

    def _scan_roles(self, channels: Sequence[int]) -> None:
        """Per scanned channel, what it carries (0 nothing, 1 angle, 2 torque) and its noise in volts, into
        the sensors record the kernel reads."""
        key = tuple(channels)
        if key != self._roles_key:
            roles = np.zeros(len(key), dtype=np.int64)
            scales = np.full(len(key), self.params.idle_channel_noise_v, dtype=np.float64)
            for j, ch in enumerate(key):
                if ch == self.joint.angle_input_channel:
                    roles[j], scales[j] = ROLE_ANGLE, self.angle_noise_v
                elif ch == self.joint.torque_input_channel:
                    roles[j], scales[j] = ROLE_TORQUE, self.torque_noise_v
            self._roles_key = key
            self._sensors = (roles, scales, *self._sensors[2:])

    def _noise(self, count: int) -> FloatArray:
        """The next `count` standard normals of the step's stream (drawn from the generator in blocks)."""
        if self._noise_pos + count > self._noise_buf.shape[0]:
            rest = self._noise_buf[self._noise_pos :]
            fresh = self.rng.standard_normal(max(NOISE_BLOCK, count - rest.shape[0]))
            self._noise_buf = np.concatenate([rest, fresh])
            self._noise_pos = 0
        return self._noise_buf[self._noise_pos : self._noise_pos + count]

    def acquire(
        self,
        t0_s: float,
        rate_hz: float,
        first_row: int,
        n_rows: int,
        channels: Sequence[int],
        until_s: float,
    ) -> tuple[FloatArray, npt.NDArray[np.int32], FloatArray]:
        """Integrate up to `until_s` and return (times, codes, volts) of scan rows first_row .. + n_rows - 1
        (row i at t0 + i / rate) — the leading part of them whose grid step has been reached (all, unless
        the last ones fall after `until_s`). Codes and volts are the DT9814's (12-bit ±10 V:
        `conversions.ai12_code_to_volts`), computed in the plant's kernel."""
        self._output.deliver()  # the commands written so far
        self._scan_roles(channels)
        n_ch = len(channels)
        noise = self._noise(n_rows * n_ch)
        t_s, codes, volts, any_nan = self.plant.scan(
            math.floor((until_s - self.origin_s) * self._inv_dt + GRID_TOL),
            (t0_s, self.origin_s, rate_hz, first_row, n_rows),
            self._sensors,
            noise,
            _AI12,
        )
        if any_nan:
            raise InvalidInput("cannot convert NaN volts to an analog input code")
        self._noise_pos += codes.shape[0] * n_ch
        return t_s, codes, volts


class ScanState:
    """A running hardware-paced scan: its channels, rate, start and rows handed out so far."""

    def __init__(self, channels: tuple[int, ...], rate_hz: float, t0_s: float, transfer_rows: int) -> None:
        self.channels = channels
        self.rate_hz = rate_hz
        self.t0_s = t0_s
        self.transfer_rows = transfer_rows
        self.rows_read = 0
        self.empty = ScanBlock.empty(len(channels))

    def rows_due(self, now_s: float) -> int:
        """Rows acquired by `now_s` and not yet read (row i at t0 + i / rate; the first at t0)."""
        n_due = math.floor((now_s - self.t0_s) * self.rate_hz + 1e-9) + 1
        return max(0, n_due - self.rows_read)

    def row_time_s(self, row: int) -> float:
        """When row `row` was acquired (the plant kernel's arithmetic: t0 + row / rate)."""
        return self.t0_s + row / self.rate_hz


class SimulatedAnalogInput:
    """A DT9814 stand-in: a hardware-paced scan of 12-bit ±10 V two's-complement codes. Reading it
    integrates the simulated robot (lazily) up to the rows it hands over: the complete transfers
    (`transfer_s`; in real time every row) acquired since the last read. Each joint's model fills its own
    angle and torque columns; a channel no joint is wired to carries the first joint's idle-channel noise."""

    def __init__(self, models: Sequence[_RigModel], clock: SimulatedClock) -> None:
        self._models = tuple(models)
        self._clock = clock
        self._channels: tuple[int, ...] = ()
        # per model reading this scan: its channels and their columns
        self._plan: list[tuple[_RigModel, tuple[int, ...], list[int]]] = []
        self._scan: ScanState | None = None
        self.transfer_s = 0.0 if clock.realtime else TRANSFER_S
        """Scan time per transfer, for the scans started from now on (0: every row as soon as it is due)."""

    @property
    def resolution_bits(self) -> int:
        return 12

    def start_scan(self, channels: Sequence[int], rate_hz: float) -> None:
        if len(channels) == 0:
            raise InvalidInput("DT9814 (simulated): a scan needs at least one channel")
        chans = tuple(check_channel(c, AI_CHANNELS, "DT9814 (simulated)") for c in channels)
        if not (math.isfinite(rate_hz) and 0.0 < rate_hz * len(chans) <= AI_MAX_RATE_HZ):
            raise InvalidInput(
                f"DT9814 (simulated): scan rate must be > 0 and at most {AI_MAX_RATE_HZ:g} samples/s over "
                f"all channels, got {rate_hz!r} Hz x {len(chans)} channels"
            )
        self._channels = chans
        owner = [next((m for m in self._models if c in m.channels), self._models[0]) for c in chans]
        self._plan = [
            (
                m,
                tuple(c for c, o in zip(chans, owner, strict=True) if o is m),
                [i for i, o in enumerate(owner) if o is m],
            )
            for m in self._models
            if m in owner
        ]
        transfer_rows = max(1, round(self.transfer_s * rate_hz))
        self._scan = ScanState(chans, float(rate_hz), self._clock.now_s(), transfer_rows)

    def _read(self, *, last: bool) -> ScanBlock:
        """The rows due and not read yet: whole transfers only, unless this is the `last` read."""
        scan = self._scan
        if scan is None:
            return ScanBlock.empty(len(self._channels))
        n_rows = scan.rows_due(self._clock.now_s())
        if not last:
            n_rows -= n_rows % scan.transfer_rows
        if n_rows <= 0:
            return scan.empty
        until_s = scan.row_time_s(scan.rows_read + n_rows - 1)
        parts = [
            m.acquire(scan.t0_s, scan.rate_hz, scan.rows_read, n_rows, chans, until_s)
            for m, chans, _ in self._plan
        ]
        if len(parts) == 1:  # one joint's model reads every column, in scan order
            t_s, codes, volts = parts[0]
        else:
            rows = {p[1].shape[0] for p in parts}
            if len(rows) != 1:
                raise InvalidInput(
                    "simulated joints on different integration grids (give them one plant_step_s)"
                )
            t_s = parts[0][0]
            codes = np.zeros((rows.pop(), len(scan.channels)), dtype=np.int32)
            volts = np.zeros(codes.shape, dtype=np.float64)
            for (_, _, cols), (_, c, v) in zip(self._plan, parts, strict=True):
                codes[:, cols] = c
                volts[:, cols] = v
        scan.rows_read += codes.shape[0]
        return ScanBlock(t_s=t_s, codes=codes, volts=volts)

    def read_available(self) -> ScanBlock:
        return self._read(last=False)

    def stop_scan(self) -> ScanBlock:
        block = self._read(last=True)
        self._scan = None
        return block

    def close(self) -> None:
        self._scan = None


class SimulatedRig:
    """The rig in a box for dry runs: a simulated clock, USB-3105 and DT9814 wired to a model of each RSST
    joint named by `joints` (its ranges, channels, calibration tables and park angle; `params`: one for
    every joint or one per joint) with or without a device under test (`set_device`). Hand `make_rig()` to
    the steps exactly as the hardware rig would be."""

    def __init__(
        self,
        joints: Sequence[JointConfig],
        *,
        seed: int = 0,
        params: SimulatorParams | Sequence[SimulatorParams] = DEFAULT_PARAMS,
        realtime: bool = False,
    ) -> None:
        self.joints = tuple(joints)
        if not self.joints:
            raise InvalidInput("a simulated rig needs at least one joint")
        each = [params] * len(self.joints) if isinstance(params, SimulatorParams) else list(params)
        if len(each) != len(self.joints):
            raise InvalidInput(f"{len(self.joints)} simulated joints need as many simulator parameter sets")
        if len({p.plant_step_s for p in each}) != 1:
            raise InvalidInput("the simulated joints of one rig need the same plant_step_s")
        self.seed = int(seed)
        self.clock = SimulatedClock(realtime=realtime)
        self.ao = SimulatedAnalogOutput(self.clock)
        several = len(self.joints) > 1
        self.models = tuple(
            _RigModel(j, p, joint_seed(self.seed, j.name) if several else self.seed, self.clock, self.ao)
            for j, p in zip(self.joints, each, strict=True)
        )
        self.ai = SimulatedAnalogInput(self.models, self.clock)
        self.begin_step("")

    def _model(self, joint: str | None) -> _RigModel:
        if joint is None:
            if len(self.models) != 1:
                raise InvalidInput(f"name the joint: the simulated rig has {len(self.models)}")
            return self.models[0]
        names = [j.name for j in self.joints]
        if joint not in names:
            raise InvalidInput(f"the simulated rig has no joint {joint!r} (it has {', '.join(names)})")
        return self.models[names.index(joint)]

    def plant(self, joint: str | None = None) -> JointPlant:
        """The physical model of `joint` (the only one when None): its real angle and load, for tests and
        diagnostics."""
        return self._model(joint).plant

    def device(self, joint: str | None = None) -> ComposedDevice | None:
        """The device fitted to `joint` (the only one when None) as the plant composed it, or None."""
        return self._model(joint).plant.device

    @property
    def step_id(self) -> str:
        return self.models[0].step_id

    def begin_step(self, step_id: str, trial: str | None = None) -> None:
        """Start step `step_id`: for every joint, reseed the noise from (its seed, step id), draw the
        between-trial spread of the friction terms from (its seed, `trial`; the step id without one), put it
        at rest at its park angle with its friction states relaxed, restart the plant's time grid now; clear
        the output records. The devices stay as fitted. Steps that name the same `trial` (a brace-on trial
        and its brace-off twin) see the same robot and device friction."""
        self.ao.clear_records()
        for m in self.models:
            m.begin_step(step_id, trial)

    def set_device(self, elements: Sequence[object] | None, *, joint: str | None = None) -> None:
        """The operator fits the device under test made of `elements` to `joint` (the only one when None),
        or removes it (with None): objects with .name, .type and .params (a mapping or (key, value) pairs,
        e.g. the protocol's resolved ElementSetting), (name, type, params) tuples, or
        `models.elements.Element`. InvalidInput names a bad element parameter."""
        self._model(joint).plant.set_device(elements)

    def make_rig(self) -> Rig:
        """A `hardware.rig.Rig` bound to this simulator's boards and clock."""
        from protocol_runner.hardware.rig import Rig

        return Rig(self.joints, self.ao, self.ai, self.clock)
