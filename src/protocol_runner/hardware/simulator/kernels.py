"""The compiled (numba) kernels of the simulated joint: integration on the time grid, the sensor chain,
and the input board's quantisation, in one call per scan read. The physics they implement is described
in `plant.py` (and docs/simulator.md); `JointPlant` holds their state and calls them.

Kernels take records, not long argument lists: the joint `(state, istate, parameters, angle table,
brakes, brake states)`, the command history, a scan's `timing` (float64) and `rows` (int64) arrays read through the named
index constants below, the sensor chain and the ADC.

They release the GIL (`nogil=True`): while the main thread simulates, the process's other threads (the
live monitor's server, the analysis pool's hand-over) run. Releasing it changes nothing in the arithmetic.
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from protocol_runner.models.element_torques import (
    cuff_shift_torque_nm,
    dahl_update,
    rom_stops_torque_nm,
    stribeck_level_nm,
    viscous_torque_nm,
)
from protocol_runner.numba_cache import cache_enabled

CACHE = cache_enabled()  # numba caches on disk unless no directory is writable (numba_cache.py)

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

# Indices into the float parameter vector handed to the kernel.
P_DT = 0
P_TAU = 1
P_EPS = 2
P_RELIEF = 3
P_T_HI = 4
P_T_LO = 5
P_GRAVITY = 6
P_GRAVITY_ZERO = 7
P_ROBOT_F = 8
P_ROBOT_TRANS = 9
P_ROBOT_VISC = 10
P_TABLE_ON = 11  # 1 when the device has angle-only torques (elastic elements, masses): the table applies
P_DAMPING = 12  # the device's viscous dampers, summed (N·m per deg/s)
P_STOPS_ON = 13
P_ROM_LO = 14
P_ROM_HI = 15
P_SLACK = 16
P_SLACK_K = 17
P_STOP_K = 18
P_BUMP_ANGLE = 19
P_BUMP_WIDTH = 20
P_BUMP_TORQUE = 21
P_BUMP_V = 22
P_TABLE_X0 = 23
P_TABLE_DX = 24
N_PARAMS = 25

# Columns of the brake array (one row per group of Coulomb brakes sharing their smoothing).
B_TORQUE = 0
B_TRANSITION = 1
B_EXCESS = 2
B_STRIBECK_V = 3
N_BRAKE_COLS = 4

# Indices into the float state vector.
S_ANGLE = 0
S_SPEED = 1
S_Z_ROBOT = 2
S_LOAD = 3
N_STATE = 4

# Indices into the integer state vector.
I_STEP = 0
I_CMD = 1
N_ISTATE = 2

#: (state, istate, parameters, angle table, brakes, brake states): the joint as the kernels see it (the
#: states are updated in place).
Joint = tuple[FloatArray, IntArray, FloatArray, FloatArray, FloatArray, FloatArray]
#: (grid step of each command, its target angle): the zero-order-hold command history.
Commands = tuple[IntArray, FloatArray]
#: (channel roles, noise volts, angle knots, their volts, torque knots, their volts).
Sensors = tuple[IntArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]
#: (volts per code, lowest code, highest code): the input board's quantisation.
Adc = tuple[float, int, int]


@njit(cache=CACHE, nogil=True)
def _load_nm(
    angle_deg: float,
    speed_deg_s: float,
    z_robot: float,
    z_brakes: FloatArray,
    p: FloatArray,
    table: FloatArray,
) -> float:
    """Total load torque the actuator holds at this state (positive = the robot pushes to +angle): the
    robot's gravity and friction, then the device's elements (`models.element_torques`)."""
    load = p[P_GRAVITY] * math.sin(math.radians(angle_deg - p[P_GRAVITY_ZERO]))
    load += z_robot + p[P_ROBOT_VISC] * speed_deg_s
    if p[P_TABLE_ON] > 0.5:
        # elastic elements and masses: linear interpolation in the precomputed table, clamped at its ends
        u = (angle_deg - p[P_TABLE_X0]) / p[P_TABLE_DX]
        n = table.shape[0]
        if u <= 0.0:
            load += table[0]
        elif u >= n - 1:
            load += table[n - 1]
        else:
            i = int(u)
            f = u - i
            load += table[i] * (1.0 - f) + table[i + 1] * f
    for g in range(z_brakes.shape[0]):
        load += z_brakes[g]
    if p[P_DAMPING] != 0.0:
        load += viscous_torque_nm(p[P_DAMPING], speed_deg_s)
    if p[P_STOPS_ON] > 0.5:
        load += rom_stops_torque_nm(
            angle_deg, p[P_ROM_LO], p[P_ROM_HI], p[P_SLACK], p[P_SLACK_K], p[P_STOP_K]
        )
    if p[P_BUMP_TORQUE] > 0.0:
        load += cuff_shift_torque_nm(
            angle_deg, speed_deg_s, p[P_BUMP_ANGLE], p[P_BUMP_WIDTH], p[P_BUMP_TORQUE], p[P_BUMP_V]
        )
    return load


@njit(cache=CACHE, nogil=True)
def integrate(
    joint: Joint,
    commands: Commands,
    n_cmd: int,
    step_end: int,
    sample_step: IntArray,
    out_angle_deg: FloatArray,
    out_torque_nm: FloatArray,
) -> int:
    """Advance the joint from its current grid step to `step_end`, recording samples on the way.

    `joint` is (state, istate, parameters, angle table, brakes, brake states); of the `commands`
    (cmd_step, cmd_target_deg), `cmd_step[:n_cmd]` / `cmd_target_deg[:n_cmd]` is the zero-order-hold command
    history: target i holds from grid step cmd_step[i] on (sorted). `sample_step` lists the grid steps (sorted) at which to record
    the real angle and the load torque into the outputs; samples at steps beyond `step_end` are left.
    Returns how many samples were written. `state` / `istate` / `z_brakes` are updated in place.
    `brakes` has one row per brake group (columns B_*), `z_brakes` its Dahl states.
    """
    state, istate, p, table, brakes, z_brakes = joint
    cmd_step, cmd_target_deg = commands
    dt = p[P_DT]
    inv_tau = 1.0 / p[P_TAU]
    eps = p[P_EPS]
    norm = math.sqrt(1.0 + eps)
    t_hi = p[P_T_HI]
    t_lo = p[P_T_LO]
    angle = state[S_ANGLE]
    speed = state[S_SPEED]
    z_r = state[S_Z_ROBOT]
    n_brakes = brakes.shape[0]
    load = state[S_LOAD]
    k = istate[I_STEP]
    ptr = istate[I_CMD]
    n_samples = sample_step.shape[0]
    j = 0
    while j < n_samples and sample_step[j] <= k:
        out_angle_deg[j] = angle
        out_torque_nm[j] = load
        j += 1
    while k < step_end:
        while ptr + 1 < n_cmd and cmd_step[ptr + 1] <= k:
            ptr += 1
        err = cmd_target_deg[ptr] - angle
        r = load / t_hi if err >= 0.0 else load / t_lo
        x = 1.0 - r
        if x < -1.0:
            x = -1.0
        elif x > 2.0:
            x = 2.0
        speed = err * inv_tau * (x / math.sqrt(abs(x) + eps)) * norm
        if load > t_hi:
            speed -= (load - t_hi) * p[P_RELIEF]
        elif load < t_lo:
            speed += (t_lo - load) * p[P_RELIEF]
        step = speed * dt
        angle += step
        z_r = dahl_update(z_r, p[P_ROBOT_F], step, p[P_ROBOT_TRANS])
        for g in range(n_brakes):
            level = stribeck_level_nm(
                brakes[g, B_TORQUE], speed, brakes[g, B_EXCESS], brakes[g, B_STRIBECK_V]
            )
            z_brakes[g] = dahl_update(z_brakes[g], level, step, brakes[g, B_TRANSITION])
        load = _load_nm(angle, speed, z_r, z_brakes, p, table)
        k += 1
        while j < n_samples and sample_step[j] <= k:
            out_angle_deg[j] = angle
            out_torque_nm[j] = load
            j += 1
    state[S_ANGLE] = angle
    state[S_SPEED] = speed
    state[S_Z_ROBOT] = z_r
    state[S_LOAD] = load
    istate[I_STEP] = k
    istate[I_CMD] = ptr
    return j


ROLE_ANGLE = 1
ROLE_TORQUE = 2
GRID_TOL = 1e-6
"""Grid rounding tolerance, in grid steps: absorbs the float error of (t - origin) / dt so that a write or
a sample exactly on a grid point lands on it whatever the clock's absolute value."""


# A scan request handed to the compiled kernels: its times (float64) and its counts (int64), by index.
T_START = 0  # t0_s: the scan's start time
T_ORIGIN = 1  # origin_s: the time of grid step 0
T_RATE = 2  # rate_hz: rows per second
N_TIMING = 3
R_STEP_END = 0  # integrate up to this grid step
R_FIRST = 1  # the first row wanted
R_COUNT = 2  # how many rows
R_N_CMD = 3  # how many commands of the history are valid
N_ROWS_REC = 4


@njit(cache=CACHE, nogil=True)
def scan_rows(
    joint: Joint,
    commands: Commands,
    timing: FloatArray,
    rows: IntArray,
    sensors: Sensors,
    noise: FloatArray,
    adc: Adc,
) -> tuple[FloatArray, npt.NDArray[np.int32], FloatArray, bool]:
    """One read of the scan in one compiled call: `integrate` up to grid step rows[R_STEP_END] for scan rows
    rows[R_FIRST] .. + rows[R_COUNT] - 1 of a scan started at timing[T_START] at timing[T_RATE] (row i at
    t0 + i / rate, sampled on grid step floor((t - origin) / dt)); each scanned channel's volts, the sensor
    chain of its role tabulated piecewise linear (angle or torque -> volts) plus `noise_v[j]` × the flat
    standard-normal `noise` (consumed row by row); then what the input board makes of them: the ADC code
    rint(V / volts_per_code) clamped to min_code..max_code (`adc` = (volts_per_code, min_code,
    max_code)) and the code's volts code · volts_per_code (the DT9814's: `conversions.ai12_code_to_volts`).
    Returns (t_s, codes, volts, any_nan) of the rows whose step was reached (a leading part); with
    any_nan the codes are meaningless (the caller raises)."""
    p = joint[2]
    roles, noise_v, angle_knots, angle_knot_volts, torque_knots, torque_knot_volts = sensors
    volts_per_code, min_code, max_code = adc
    t0_s = timing[T_START]
    origin_s = timing[T_ORIGIN]
    rate_hz = timing[T_RATE]
    first_row = rows[R_FIRST]
    n_rows = rows[R_COUNT]
    inv_dt = 1.0 / p[P_DT]
    steps = np.empty(n_rows, dtype=np.int64)
    for i in range(n_rows):
        t = t0_s + (first_row + i) / rate_hz
        step = math.floor((t - origin_s) * inv_dt + GRID_TOL)
        steps[i] = step if step > 0 else 0
    angle = np.empty(n_rows, dtype=np.float64)
    torque = np.empty(n_rows, dtype=np.float64)
    got = integrate(joint, commands, rows[R_N_CMD], rows[R_STEP_END], steps, angle, torque)
    a_v = np.interp(angle[:got], angle_knots, angle_knot_volts)
    t_v = np.interp(torque[:got], torque_knots, torque_knot_volts)
    n_ch = roles.shape[0]
    t_s = np.empty(got, dtype=np.float64)
    codes = np.empty((got, n_ch), dtype=np.int32)
    volts = np.empty((got, n_ch), dtype=np.float64)
    any_nan = False
    lo = float(min_code)
    hi = float(max_code)
    for i in range(got):
        t_s[i] = t0_s + float(first_row + i) / rate_hz
        for j in range(n_ch):
            v = noise_v[j] * noise[i * n_ch + j]
            if roles[j] == ROLE_ANGLE:
                v += a_v[i]
            elif roles[j] == ROLE_TORQUE:
                v += t_v[i]
            if math.isnan(v):
                any_nan = True
                codes[i, j] = 0
                volts[i, j] = 0.0
                continue
            k = np.rint(v / volts_per_code)
            if k < lo:
                k = lo
            elif k > hi:
                k = hi
            c = np.int32(k)
            codes[i, j] = c
            volts[i, j] = float(c) * volts_per_code
    return t_s, codes, volts, any_nan
