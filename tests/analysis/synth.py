"""Synthetic rig data with known answers, for the analysis tests (no simulator needed).

The robot's own torque and the brace's torque are functions of (angle, direction of motion) only, so the
exact brace torque of every brace-on sample is known and equal-angle subtraction can be checked against it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

INPUT_RATE_HZ = 1000.0
OUTPUT_RATE_HZ = 100.0


def sine_command(mean_deg: float, amplitude_deg: float, period_s: float, duration_s: float, rate_hz: float):
    """Appendix A Eq 24 trajectory: mean + amplitude sin(2 pi t / period), sampled at rate_hz."""
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    return t, mean_deg + amplitude_deg * np.sin(2 * np.pi * t / period_s)


def first_order_lag(command_deg: FloatArray, dt_s: float, tau_s: float, start_deg: float) -> FloatArray:
    """Exact zero-order-hold discretisation of a first-order lag x' = (u - x) / tau."""
    k = np.exp(-dt_s / tau_s)
    out = np.empty_like(command_deg)
    x = start_deg
    for i, u in enumerate(command_deg):
        out[i] = x
        x = k * x + (1 - k) * u
    return out


def direction(angle_deg: FloatArray) -> FloatArray:
    """+1 while the angle increases, -1 while it decreases (exact, for noise-free smooth signals)."""
    d = np.gradient(angle_deg)
    s = np.sign(d)
    # fill zeros (exact turning points) with the previous direction
    for i in range(1, s.shape[0]):
        if s[i] == 0:
            s[i] = s[i - 1]
    if s[0] == 0:
        s[0] = 1.0
    return s


def robot_torque_nm(angle_deg: FloatArray, direction_sign: FloatArray) -> FloatArray:
    """The bare robot: shank gravity (strongly angle dependent) plus its own friction per branch."""
    return 35.0 * np.sin(np.radians(angle_deg)) + 4.0 * direction_sign


def brace_torque_nm(
    angle_deg: FloatArray, direction_sign: FloatArray, friction_nm: float = 3.0
) -> FloatArray:
    """A brace: a nonlinear spring about 20 deg plus Coulomb friction of the brake per branch."""
    spring = 0.4 * (angle_deg - 20.0) + 0.002 * (angle_deg - 20.0) ** 2
    return spring + friction_nm * direction_sign


@dataclass(frozen=True)
class PairData:
    time_s: FloatArray
    command_deg: FloatArray
    angle_on_deg: FloatArray
    torque_on_nm: FloatArray
    brace_true_nm: FloatArray
    angle_off_deg: FloatArray
    torque_off_nm: FloatArray


def brace_pair(seed: int = 0, noise: bool = False, friction_nm: float = 3.0) -> PairData:
    """A brace-on and a brace-off trial on a 1 kHz time base, already past their transitions.

    Brace-on: lagging more (tau 0.35 s) and limited to about 28-104 deg by the brace's resistance;
    brace-off: the full 5-125 deg, tau 0.2 s. Angle ranges and timing differ, as on the rig.
    """
    t, cmd = sine_command(65.0, 60.0, 8.0, 40.0, INPUT_RATE_HZ)
    dt = 1.0 / INPUT_RATE_HZ
    off = first_order_lag(cmd, dt, 0.2, cmd[0])
    on_raw = first_order_lag(cmd, dt, 0.35, cmd[0])
    # the brace squeezes the range smoothly: 65 + 38 tanh((x - 65) / 38) -> about [28, 104]
    on = 66.0 + 38.0 * np.tanh((on_raw - 66.0) / 38.0)
    dir_on = direction(on)
    dir_off = direction(off)
    brace = brace_torque_nm(on, dir_on, friction_nm)
    torque_on = robot_torque_nm(on, dir_on) + brace
    torque_off = robot_torque_nm(off, dir_off)
    if noise:
        rng = np.random.default_rng(seed)
        on = on + rng.normal(0.0, 0.05, on.shape)
        off = off + rng.normal(0.0, 0.05, off.shape)
        torque_on = torque_on + rng.normal(0.0, 0.3, on.shape)
        torque_off = torque_off + rng.normal(0.0, 0.3, off.shape)
    return PairData(t, cmd, on, torque_on, brace, off, torque_off)
