"""The ROBOT side of the DAQ simulator's rig model: the servo, the joint's own loads, the sensors and the
numerics (docs/simulator.md explains the model).

The device under test is not here: it arrives as composed elements (`SimulatedRig.set_device`,
`models.elements`), with its parameters from the protocol. The defaults below are generic (a bare joint
with the 0.2 s lag of thesis §2.4.2, no segment weight, no friction of its own): each joint's values come
from the rig file's `simulator:` mapping (keys = these field names), e.g. the knee's shank weight and
friction, chosen so that the simulated knee reproduces the findings of thesis §5 (docs/simulator.md).

Angles are in degrees and angular speeds in deg/s throughout the simulator (the thesis's units), torques in
N·m, forces in N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from protocol_runner.errors import InvalidInput


@dataclass(frozen=True)
class SimulatorParams:
    """The rig model's constants (see the module docstring; docs/simulator.md has the same table)."""

    # --- integration -------------------------------------------------------------------------------------
    plant_step_s: float = 0.0005
    """Fixed integration step (2 kHz). Half the 1 kHz scan period, so that stiff range-of-motion stops
    (40 N·m/deg) integrate stably with explicit Euler; samples are taken on this grid."""

    # --- the robot joint: hydraulic position servo (thesis §2.2, §2.4.2) ---------------------------------
    lag_time_constant_s: float = 0.2
    """Time constant of the unloaded servo (first-order lag, valve flow proportional to position error).
    The thesis measured 0.2 s on the loaded joint (§2.4.2, Figures 18-19). A joint whose segment weight
    slows its calibration step gets a shorter unloaded value from the rig file (the knee: 0.17 s gives the
    measured 0.2 s on its loaded 45° step, tests/hardware/test_simulator.py fits it)."""

    valve_regularisation: float = 0.02
    """The actuator's speed is scaled by the valve's pressure-flow law g(x) = x/sqrt(|x| + ε)·sqrt(1 + ε),
    x = 1 - load/limit (orifice flow ∝ sqrt(supply - load pressure); it falls to zero at the torque limit
    and reverses beyond it). ε rounds the square root's infinite slope at the stall point so that explicit
    integration does not chatter. Pure numerics: any value 0.005-0.05 behaves the same."""

    relief_speed_deg_s_per_nm: float = 5.0
    """When the load exceeds the torque limit (e.g. a stiff stop pressed by a still command) the actuator
    yields like a relief valve: it is back-driven at this speed per N·m of excess. Numerics: large enough to
    keep the load at the limit, small enough to be stable with the stiffest stop."""

    # --- loads of the bare robot (present in every trial) ------------------------------------------------
    gravity_torque_max_nm: float = 0.0
    """m·g·l of the segment the joint carries: the gravity torque where the segment is horizontal. The
    rig file gives each joint's (the knee's shank: 35.5 N·m, see docs/simulator.md for the finding it
    pins)."""

    gravity_zero_angle_deg: float = 0.0
    """Joint angle at which the segment hangs vertically (no gravity torque); gravity torque =
    gravity_torque_max_nm · sin(angle - this)."""

    robot_friction_nm: float = 0.0
    """Coulomb friction of the robot's own actuator and seals (a Dahl hysteresis state, thesis §5: the
    hysteresis every graph shows is "an artifact of the robot"). Per joint, from the rig file."""

    robot_friction_transition_deg: float = 1.5
    """Displacement over which the robot's friction state relaxes to a new direction (Dahl σ = F / this):
    rounded loop corners as in the thesis's hysteresis plots (Appendix B)."""

    robot_viscous_nm_per_deg_s: float = 0.0
    """Viscous friction of the actuator (hydraulic fluid), N·m per deg/s. Per joint, from the rig file."""

    spring_table_step_deg: float = 0.25
    """Resolution of the precomputed torque-vs-angle table of the device's elastic elements and masses
    (`models.element_torques.static_torque_nm`, linearly interpolated in the integrator). Below 0.01 N·m
    error on the knee brace's springs."""

    # --- sensors (thesis §2.2, §3.2) ---------------------------------------------------------------------
    angle_noise_deg: float = 0.1
    """White noise on the potentiometer telemetry, 1σ. About 3 LSB of the 12-bit DT9814 on the knee's
    0-130° range. Chosen."""

    torque_noise_nm: float = 0.8
    """White noise on the load-cell telemetry, 1σ. Thesis §3.2: "the data output from the robot is very
    noisy" — the torque needs the 10th-order Butterworth filter of §4.4. Chosen."""

    idle_channel_noise_v: float = 0.005
    """Noise on scanned channels that carry no simulated signal (about 1 LSB)."""

    # --- between-trial spread (a rig is not the same from one trial to the next) ---------------------------
    trial_spread_robot_friction_cv: float = 0.0
    """Coefficient of variation between trials of the robot's Coulomb friction (`robot_friction_nm`):
    each trial multiplies it by a factor drawn once for the trial (`trial_factors`). 0 = every trial the
    same. Per joint, from the rig file."""

    trial_spread_robot_viscous_cv: float = 0.0
    """The same for the robot's viscous friction (`robot_viscous_nm_per_deg_s`)."""

    trial_spread_device_friction_cv: float = 0.0
    """The same for the device's dissipative elements (its Coulomb brakes' torques and its viscous dampers,
    one factor for all of them): the brace as fitted for that trial. Its springs, masses and stops do not
    vary (their parameters are set by parts, not by fitting)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise InvalidInput(f"simulator parameter {f.name} must be a finite number, got {value!r}")
            problem = bound_problem(f.name, value)
            if problem:
                raise InvalidInput(f"simulator parameter {f.name} {problem}")


# Where the work of a simulated trial grows with a parameter (steps per second, table entries), its range:
# the defaults are well inside, and the ends keep a trial's work and memory bounded.
BOUNDS = {
    "plant_step_s": (1.0e-5, 0.01),  # integration grid: 100 kHz at most (the default is 2 kHz)
    "lag_time_constant_s": (1.0e-3, 10.0),
    "robot_friction_transition_deg": (1.0e-3, 90.0),
    "spring_table_step_deg": (1.0e-3, 10.0),  # a table of at most 720,000 entries over +-360 deg
    # a spread beyond 50 % is no longer the same rig
    "trial_spread_robot_friction_cv": (0.0, 0.5),
    "trial_spread_robot_viscous_cv": (0.0, 0.5),
    "trial_spread_device_friction_cv": (0.0, 0.5),
}


SIGNED = ("gravity_zero_angle_deg",)  # the parameters that may be negative


def bound_problem(name: str, value: float) -> str:
    """What is wrong with `value` for simulator parameter `name` ("" if nothing): outside its BOUNDS, or
    negative where only SIGNED ones may be."""
    if not isinstance(value, int | float):
        return ""
    low_high = BOUNDS.get(name)
    if low_high is None:
        return f"must be >= 0, got {value!r}" if value < 0.0 and name not in SIGNED else ""
    low, high = low_high
    if not low <= value <= high:
        return f"must lie in [{low:g}, {high:g}], got {value!r}"
    return ""


DEFAULT_PARAMS = SimulatorParams()
"""The documented defaults."""


TrialFactors = tuple[float, float, float]
"""One trial's multipliers of (robot Coulomb friction, robot viscous friction, device friction)."""

SAME_EVERY_TRIAL: TrialFactors = (1.0, 1.0, 1.0)


def trial_factors(params: SimulatorParams, rng: np.random.Generator) -> TrialFactors:
    """One trial's draw of the between-trial spread: for each of the robot's Coulomb friction, its viscous
    friction and the device's friction, a log-normal factor of mean 1 and the parameter's coefficient of
    variation (always positive; exactly 1 with a CV of 0). Three standard normals are drawn from `rng`
    whatever the CVs, so one CV does not change the others' draws."""
    normals = rng.standard_normal(3)
    cvs = (
        params.trial_spread_robot_friction_cv,
        params.trial_spread_robot_viscous_cv,
        params.trial_spread_device_friction_cv,
    )
    out = []
    for cv, z in zip(cvs, normals, strict=True):
        sigma = math.sqrt(math.log1p(cv * cv))
        out.append(math.exp(sigma * float(z) - 0.5 * sigma * sigma))
    return (out[0], out[1], out[2])
