"""The block path's compiled call (issue 20): a block of scheduled output writes and the input scan read at
its last write, in one numba call — the USB-3105's codes, the robot's decoding of them into commands, the
plant, the sensors and the DT9814's codes together.

It does, sample for sample, what the per-tick path does through Python (`SimulatedAnalogOutput.write_volts`
-> `_RigModel.on_write` -> `JointPlant.push_command` for every write, then `JointPlant.scan` at the read):

- code: k = 32768 + 3276.8 V rounded half to even, clamped to 0..65535 (±inf clamp; NaN refused) — the
  board's rule (`usb3105.calibrated_code` with ideal calibration, = `conversions.volts_to_ao16_code`);
- command: that code's target (the robot's decoding table) from grid step ceil((t - origin)/dt - 1e-6), not
  before the step already integrated, in time order;
- then `kernels.scan_rows` over the rows due at the block's last write.

Everything is validated before anything changes: a NaN or a write out of time order returns a status and
leaves the plant untouched. The compiled call releases the GIL (the unit writer thread runs meanwhile).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from protocol_runner.hardware.simulator.kernels import (
    GRID_TOL,
    I_STEP,
    P_DT,
    R_N_CMD,
    Commands,
    FloatArray,
    IntArray,
    Joint,
    Sensors,
    scan_rows,
)
from protocol_runner.numba_cache import cache_enabled

CACHE = cache_enabled()  # numba caches on disk unless no directory is writable (numba_cache.py)

BLOCK_OK = 0
BLOCK_NAN = 1
BLOCK_OUT_OF_ORDER = 2

AO16_ZERO = 32768.0
AO16_PER_VOLT = 3276.8
AO16_MAX = 65535.0

#: (each output code's commanded real angle, time of grid step 0, 1 if the writes move the joint else 0)
Decode = tuple[FloatArray, float, int]


@njit(cache=CACHE, nogil=True)
def ao16_code(volts: float) -> int:
    """The USB-3105's ±10 V code of `volts` (not NaN): rint(32768 + 3276.8 V) clamped to 0..65535."""
    k = np.rint(AO16_ZERO + AO16_PER_VOLT * volts)
    if k < 0.0:
        return 0
    if k > AO16_MAX:
        return 65535
    return int(k)


@njit(cache=CACHE, nogil=True)
def send_and_scan(
    joint: Joint,
    commands: Commands,
    block: tuple[FloatArray, FloatArray],
    decode: Decode,
    timing: FloatArray,
    rows: IntArray,
    sensors: Sensors,
    noise: FloatArray,
    adc: tuple[float, int, int],
) -> tuple[IntArray, int, int, FloatArray, npt.NDArray[np.int32], FloatArray, bool]:
    """Write the block (`block` = (times, volts)), append its commands to the history after its first
    rows[R_N_CMD] entries (the arrays have room), then `scan_rows` with the longer history. Returns (codes,
    commands in the history, status, row times, row codes, row volts, any NaN volts); on a status other
    than BLOCK_OK nothing was changed."""
    state, istate, p, table, brakes, z_brakes = joint
    cmd_step, cmd_target = commands
    times, volts = block
    target_by_code, origin_s, moves = decode
    n = times.shape[0]
    n_cmd = rows[R_N_CMD]
    codes = np.empty(n, dtype=np.int64)
    steps = np.empty(n, dtype=np.int64)
    empty_t = np.empty(0, dtype=np.float64)
    empty_c = np.empty((0, 0), dtype=np.int32)
    empty_v = np.empty((0, 0), dtype=np.float64)
    inv_dt = 1.0 / p[P_DT]
    held = istate[I_STEP]
    last = cmd_step[n_cmd - 1] if n_cmd > 0 else 0
    for i in range(n):
        if math.isnan(volts[i]):
            return codes, n_cmd, BLOCK_NAN, empty_t, empty_c, empty_v, False
        codes[i] = ao16_code(volts[i])
        k = math.ceil((times[i] - origin_s) * inv_dt - GRID_TOL)
        if k < held:
            k = held
        if moves and k < last:
            return codes, n_cmd, BLOCK_OUT_OF_ORDER, empty_t, empty_c, empty_v, False
        steps[i] = k
        last = k
    if moves:
        for i in range(n):
            cmd_step[n_cmd] = steps[i]
            cmd_target[n_cmd] = target_by_code[codes[i]]
            n_cmd += 1
    rows[R_N_CMD] = n_cmd
    t_s, row_codes, row_volts, any_nan = scan_rows(
        (state, istate, p, table, brakes, z_brakes), commands, timing, rows, sensors, noise, adc
    )
    return codes, n_cmd, BLOCK_OK, t_s, row_codes, row_volts, any_nan
