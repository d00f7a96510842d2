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
    """The rig model's constants. docs/simulator.md ("Parameters") gives each one's meaning, its knee value
    and the source or finding behind it; the servo law that `valve_regularisation` (ε) and
    `relief_speed_deg_s_per_nm` enter is stated there too."""

    # integration: 2 kHz, half the 1 kHz scan period, stable with 40 N·m/deg stops under explicit Euler
    plant_step_s: float = 0.0005
    # the robot joint: hydraulic position servo (thesis §2.2, §2.4.2), first-order lag of the unloaded joint
    lag_time_constant_s: float = 0.2
    valve_regularisation: float = 0.02
    relief_speed_deg_s_per_nm: float = 5.0
    # loads of the bare robot, present in every trial: gravity = gravity_torque_max_nm · sin(angle - zero)
    gravity_torque_max_nm: float = 0.0
    gravity_zero_angle_deg: float = 0.0
    robot_friction_nm: float = 0.0  # Coulomb (Dahl state, σ = F / transition)
    robot_friction_transition_deg: float = 1.5
    robot_viscous_nm_per_deg_s: float = 0.0
    spring_table_step_deg: float = 0.25  # the device's torque-vs-angle table (`models.element_torques`)
    # sensors (thesis §2.2, §3.2): white noise, 1σ
    angle_noise_deg: float = 0.1
    torque_noise_nm: float = 0.8
    idle_channel_noise_v: float = 0.005  # channels that carry no simulated signal
    # between-trial spread: coefficients of variation of the robot's Coulomb and viscous friction and of the
    # device's brakes and dampers (one factor for all; its springs, masses and stops do not vary), each
    # drawn once per trial by `trial_factors`; 0 = every trial the same
    trial_spread_robot_friction_cv: float = 0.0
    trial_spread_robot_viscous_cv: float = 0.0
    trial_spread_device_friction_cv: float = 0.0

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
