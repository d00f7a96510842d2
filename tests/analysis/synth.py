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


@dataclass(frozen=True)
class RawTrial:
    """One recorded trial as archived: 1 kHz time/angle/torque, 100 Hz command ticks."""

    time_s: FloatArray
    angle_deg: FloatArray
    torque_nm: FloatArray
    command_time_s: FloatArray
    command_deg: FloatArray
    brace_true_nm: FloatArray  # the brace's own torque per sample (zeros for brace-off)


def raw_trial(*, brace: bool, seed: int, friction_nm: float = 3.0, duration_s: float = 34.0) -> RawTrial:
    """A trial from the park angle (0 deg) through the start-up transition, with sensor noise.

    The command is the Appendix A sinusoid 65 + 60 sin(2 pi t / 8) on 100 Hz ticks; the joint is a
    first-order lag of the held command (0.2 s bare, 0.3 s and a range squeezed by 0.8 about 65 deg with
    the brace). Torque: robot (gravity + friction per branch) plus, with the brace, `brace_torque_nm`.
    """
    t_cmd, cmd = sine_command(65.0, 60.0, 8.0, duration_s, OUTPUT_RATE_HZ)
    t_in = np.arange(0.0, duration_s, 1.0 / INPUT_RATE_HZ)
    held = cmd[np.clip(np.searchsorted(t_cmd, t_in, side="right") - 1, 0, cmd.shape[0] - 1)]
    if brace:
        lagged = first_order_lag(held, 1.0 / INPUT_RATE_HZ, 0.3, 0.0)
        angle = 65.0 + 0.8 * (lagged - 65.0)
    else:
        angle = first_order_lag(held, 1.0 / INPUT_RATE_HZ, 0.2, 0.0)
    sign = direction(angle)
    brace_nm = brace_torque_nm(angle, sign, friction_nm) if brace else np.zeros_like(angle)
    torque = robot_torque_nm(angle, sign) + brace_nm
    rng = np.random.default_rng(seed)
    return RawTrial(
        time_s=t_in,
        angle_deg=angle + rng.normal(0.0, 0.05, angle.shape),
        torque_nm=torque + rng.normal(0.0, 0.3, angle.shape),
        command_time_s=t_cmd,
        command_deg=cmd,
        brace_true_nm=brace_nm,
    )
