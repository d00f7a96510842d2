"""The rig's physics: an RSST joint (hydraulic position servo) and the device under test, integrated by numba.
docs/simulator.md ("The joint", "Loads") states the model; every constant is in `params.py`.

The joint is a flow (speed) source whose speed collapses as the load nears its torque limit τ_limit (the
joint's Eq 3 range in the direction it pushes, thesis Table 3, §5), with e = target - angle:

    dθ/dt = (e / τ) · g(1 - τ_load / τ_limit),     g(x) = x / sqrt(|x| + ε) · sqrt(1 + ε)

plus a relief term for a load beyond the limit. The load, in the sign convention of `models.spring`
(positive = the robot must push towards flexion), is the segment's gravity G · sin(θ - θ_0), the robot's
friction (a Dahl state z_r + viscous c·dθ/dt) and the device's elements as `device.compose` groups them
(equations in `models.element_torques`). Explicit Euler on a fixed grid (`plant_step_s`); the Dahl states
use the exact exponential update over each step, so they are unconditionally stable. Deterministic.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from protocol_runner.hardware.simulator import kernels as K
from protocol_runner.hardware.simulator.device import ComposedDevice, as_elements, compose
from protocol_runner.hardware.simulator.kernels import Adc, Commands, FloatArray, IntArray, Joint, Sensors
from protocol_runner.hardware.simulator.params import SAME_EVERY_TRIAL, SimulatorParams, TrialFactors
from protocol_runner.models.elements import Element

ScanWindow = tuple[float, float, float, int, int]
"""A read of scan rows: (t0 s, grid origin s, rate Hz, first row, number of rows); row i is at t0 + i / rate."""


class JointPlant:
    """One simulated joint (with or without a device under test) on a fixed time grid of
    `params.plant_step_s`.

    Time is counted in grid steps from the last `reset`. Commands are real target angles (the robot's own
    input nonlinearity already applied by the caller) holding from a grid step on; `advance` integrates up
    to a grid step and returns the real angle and load torque at the requested sample steps.
    """

    def __init__(
        self,
        params: SimulatorParams,
        range_deg: tuple[float, float],
        torque_range_nm: tuple[float, float],
    ) -> None:
        self.params = params
        self.range_deg = (float(range_deg[0]), float(range_deg[1]))
        t_lo, t_hi = float(torque_range_nm[0]), float(torque_range_nm[1])
        if not (t_lo < 0.0 < t_hi):
            raise ValueError(f"torque range must straddle 0 N·m, got {torque_range_nm!r}")
        p = np.zeros(K.N_PARAMS, dtype=np.float64)
        p[K.P_DT] = params.plant_step_s
        p[K.P_TAU] = params.lag_time_constant_s
        p[K.P_EPS] = params.valve_regularisation
        p[K.P_RELIEF] = params.relief_speed_deg_s_per_nm
        p[K.P_T_HI] = t_hi
        p[K.P_T_LO] = t_lo
        p[K.P_GRAVITY] = params.gravity_torque_max_nm
        p[K.P_GRAVITY_ZERO] = params.gravity_zero_angle_deg
        p[K.P_ROBOT_F] = params.robot_friction_nm
        p[K.P_ROBOT_TRANS] = params.robot_friction_transition_deg
        p[K.P_ROBOT_VISC] = params.robot_viscous_nm_per_deg_s
        p[K.P_TABLE_DX] = params.spring_table_step_deg
        self._p = p
        self._table = np.zeros(2, dtype=np.float64)
        self._brakes = np.zeros((0, K.N_BRAKE_COLS), dtype=np.float64)
        self._z_brakes = np.zeros(0, dtype=np.float64)
        self.device: ComposedDevice | None = None
        self._state = np.zeros(K.N_STATE, dtype=np.float64)
        self._istate = np.zeros(K.N_ISTATE, dtype=np.int64)
        self._cmd_step = np.zeros(1024, dtype=np.int64)
        self._cmd_target = np.zeros(1024, dtype=np.float64)
        self._n_cmd = 0
        self.trial_factors: TrialFactors = SAME_EVERY_TRIAL
        self.set_device(None)
        self.reset(0.5 * (self.range_deg[0] + self.range_deg[1]))

    # --- set-up ---------------------------------------------------------------------------------------
    def set_device(self, elements: Sequence[Element] | Sequence[object] | None) -> None:
        """Fit (or remove, with None or no elements) the device under test: its elements composed
        (`device.compose`). Resets the device's friction states; keeps the joint's."""
        p = self._p
        found = as_elements(elements)
        dev = compose(found, self.range_deg, self.params.spring_table_step_deg) if found else None
        self.device = dev
        p[K.P_TABLE_ON] = p[K.P_TABLE_X0] = p[K.P_STOPS_ON] = p[K.P_BUMP_TORQUE] = 0.0
        self._table = np.zeros(2, dtype=np.float64)
        if dev is not None:
            if dev.table is not None:
                p[K.P_TABLE_ON], p[K.P_TABLE_X0], self._table = 1.0, dev.table_x0_deg, dev.table
            if dev.stops is not None:
                p[K.P_STOPS_ON] = 1.0
                p[K.P_ROM_LO], p[K.P_ROM_HI], p[K.P_SLACK], p[K.P_SLACK_K], p[K.P_STOP_K] = dev.stops
            if dev.bump is not None:
                p[K.P_BUMP_ANGLE], p[K.P_BUMP_WIDTH], p[K.P_BUMP_TORQUE], p[K.P_BUMP_V] = dev.bump
        self._apply_factors()
        self._z_brakes = np.zeros(self._brakes.shape[0], dtype=np.float64)
        self._refresh_load()

    def set_trial_factors(self, factors: TrialFactors) -> None:
        """This trial's multipliers of the robot's Coulomb and viscous friction and of the device's
        friction (`params.trial_factors`); they hold, whatever device is fitted, until the next call."""
        self.trial_factors = factors
        self._apply_factors()
        self._refresh_load()

    def _apply_factors(self) -> None:
        """The friction terms of the robot and of the fitted device times this trial's factors."""
        robot_friction, robot_viscous, device_friction = self.trial_factors
        p, dev = self._p, self.device
        p[K.P_ROBOT_F] = self.params.robot_friction_nm * robot_friction
        p[K.P_ROBOT_VISC] = self.params.robot_viscous_nm_per_deg_s * robot_viscous
        self._brakes = np.zeros((0, K.N_BRAKE_COLS), dtype=np.float64)
        p[K.P_DAMPING] = 0.0
        if dev is not None:
            self._brakes = dev.brakes.copy()
            self._brakes[:, K.B_TORQUE] *= device_friction
            p[K.P_DAMPING] = dev.damping_nm_s_per_deg * device_friction

    def reset(self, angle_deg: float) -> None:
        """Put the joint at rest at `angle_deg`, friction states relaxed, holding that angle as its command,
        at grid step 0. If the load there exceeds the actuator's limit (a brace stop set beyond the park
        angle), the joint rests instead where the load equals the limit: the stop pushed it that far."""
        self._state[:] = 0.0
        self._z_brakes[:] = 0.0
        self._state[K.S_ANGLE] = self._rest_angle_deg(float(angle_deg))
        self._istate[:] = 0
        self._n_cmd = 0
        self.push_command(0, float(angle_deg))
        self._refresh_load()

    def load_at_nm(self, angle_deg: float, speed_deg_s: float = 0.0) -> float:
        """The load torque at `angle_deg` moving at `speed_deg_s` with the friction states relaxed (z = 0):
        gravity + viscous + the device's elastic elements, masses, dampers, stops and cuff shift (for
        diagnostics and tests)."""
        zero = np.zeros(self._brakes.shape[0], dtype=np.float64)
        return float(K._load_nm(float(angle_deg), float(speed_deg_s), 0.0, zero, self._p, self._table))

    def _rest_angle_deg(self, angle_deg: float) -> float:
        t_lo, t_hi = self._p[K.P_T_LO], self._p[K.P_T_HI]
        load = self.load_at_nm(angle_deg)
        if t_lo <= load <= t_hi:
            return angle_deg
        # the load falls back inside the limits towards the middle of the device's stops
        limit = t_hi if load > t_hi else t_lo
        towards = (
            0.5 * (self._p[K.P_ROM_LO] + self._p[K.P_ROM_HI]) if self._p[K.P_STOPS_ON] > 0.5 else angle_deg
        )
        a, b = angle_deg, towards
        if (self.load_at_nm(b) - limit) * (load - limit) > 0.0:
            return angle_deg  # no crossing: leave it (the relief term will act)
        for _ in range(60):
            mid = 0.5 * (a + b)
            if (self.load_at_nm(mid) - limit) * (load - limit) > 0.0:
                a = mid
            else:
                b = mid
        return 0.5 * (a + b)

    def _refresh_load(self) -> None:
        s = self._state
        s[K.S_LOAD] = K._load_nm(
            s[K.S_ANGLE], s[K.S_SPEED], s[K.S_Z_ROBOT], self._z_brakes, self._p, self._table
        )

    # --- running --------------------------------------------------------------------------------------
    @property
    def step(self) -> int:
        """The grid step the joint has been integrated to."""
        return int(self._istate[K.I_STEP])

    @property
    def angle_deg(self) -> float:
        """The joint's real angle now."""
        return float(self._state[K.S_ANGLE])

    @property
    def load_nm(self) -> float:
        """The load torque the actuator holds now (what the load cell sees)."""
        return float(self._state[K.S_LOAD])

    def push_command(self, step: int, target_deg: float) -> None:
        """Hold `target_deg` (a real angle) from grid step `step` on (see `push_commands`)."""
        self.push_commands(np.array([step], dtype=np.int64), np.array([target_deg], dtype=np.float64))

    def push_commands(self, steps: IntArray, targets_deg: FloatArray) -> None:
        """Hold targets_deg[i] (real angles) from grid step steps[i] on. Steps must not go backwards; a step
        already integrated past is applied from the current step; of several commands for the same step
        the last one holds."""
        n_new = int(steps.shape[0])
        if n_new == 0:
            return
        steps = np.maximum(steps, self._istate[K.I_STEP])
        last = self._cmd_step[self._n_cmd - 1] if self._n_cmd else 0
        if steps[0] < last or bool(np.any(steps[1:] < steps[:-1])):
            raise ValueError("commands must be pushed in time order")
        n_keep = self._reserve(n_new)
        self._cmd_step[n_keep : n_keep + n_new] = steps
        self._cmd_target[n_keep : n_keep + n_new] = targets_deg
        self._n_cmd = n_keep + n_new

    def _reserve(self, n_new: int) -> int:
        """Room for `n_new` more commands in the kernel's arrays; returns how many are kept. Commands before
        the current one are never needed again: compacted away instead of growing forever."""
        keep_from = int(self._istate[K.I_CMD])
        n_keep = self._n_cmd - keep_from
        if keep_from > 0:
            self._cmd_step[:n_keep] = self._cmd_step[keep_from : self._n_cmd]
            self._cmd_target[:n_keep] = self._cmd_target[keep_from : self._n_cmd]
            self._istate[K.I_CMD] = 0
            self._n_cmd = n_keep
        needed = n_keep + n_new
        if needed > self._cmd_step.shape[0]:
            size = max(needed, 2 * self._cmd_step.shape[0])
            self._cmd_step = np.concatenate([self._cmd_step[:n_keep], np.zeros(size - n_keep, np.int64)])
            self._cmd_target = np.concatenate([self._cmd_target[:n_keep], np.zeros(size - n_keep)])
        return n_keep

    def scan(
        self, step_end: int, scan: ScanWindow, sensors: Sensors, noise: FloatArray, adc: Adc
    ) -> tuple[FloatArray, npt.NDArray[np.int32], FloatArray, bool]:
        """Integrate to `step_end` and read the `scan` window's rows as the input board does
        (`kernels.scan_rows`): `sensors` = (roles, noise volts, angle knots, their volts, torque knots, their
        volts); `noise` holds at least n_rows × channels standard normals, consumed row by row; `adc` =
        (volts per code, lowest code, highest code). Returns (row times, codes, their volts, whether any
        volts were NaN)."""
        return K.scan_rows(*self._window(step_end, scan), sensors, noise, adc)

    def _window(self, step_end: int, scan: ScanWindow) -> tuple[Joint, Commands, FloatArray, IntArray]:
        """The kernels' (joint, commands, timing, rows) records for reading the `scan` window's rows after
        integrating to `step_end`."""
        t0_s, origin_s, rate_hz, first_row, n_rows = scan
        timing = np.empty(K.N_TIMING, dtype=np.float64)
        timing[K.T_START], timing[K.T_ORIGIN], timing[K.T_RATE] = float(t0_s), float(origin_s), float(rate_hz)
        rows = np.empty(K.N_ROWS_REC, dtype=np.int64)
        rows[K.R_STEP_END], rows[K.R_FIRST], rows[K.R_COUNT] = int(step_end), int(first_row), int(n_rows)
        rows[K.R_N_CMD] = self._n_cmd
        return self._joint(), (self._cmd_step, self._cmd_target), timing, rows

    def _joint(self) -> Joint:
        return (self._state, self._istate, self._p, self._table, self._brakes, self._z_brakes)

    def advance(self, step_end: int, sample_step: IntArray) -> tuple[FloatArray, FloatArray]:
        """Integrate to grid step `step_end`; return (real angle, load torque) at each of the sorted
        `sample_step` that is <= step_end (the prefix of `sample_step` that could be sampled)."""
        n = sample_step.shape[0]
        angle = np.empty(n, dtype=np.float64)
        torque = np.empty(n, dtype=np.float64)
        commands = (self._cmd_step, self._cmd_target)
        steps = np.ascontiguousarray(sample_step, dtype=np.int64)
        got = K.integrate(self._joint(), commands, self._n_cmd, int(step_end), steps, angle, torque)
        return angle[:got], torque[:got]
