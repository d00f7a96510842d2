"""Every constant of the DAQ simulator's rig model, in one place, each with its source or the reason for
its value (DESIGN.md "The DAQ simulator"; docs/simulator.md explains the model).

Two kinds of values live here:

- facts from the thesis (the 0.2 s first-order lag of §2.4.2, the torque limit of Table 3 — taken from the
  protocol's joint, not from here —, the friction levels and springs of Appendix A, which arrive through a
  `BraceSetup`), and
- *chosen* values where the thesis gives no number (the shank's weight, the robot's own friction, the
  misalignment slack, sensor noise). Each chosen value is set so that the simulated rig reproduces a
  qualitative finding of thesis §5 while staying physically plausible; the docstring of each field says
  which finding pins it.

Angles are in degrees and angular speeds in deg/s throughout the simulator (the thesis's units), torques in
N·m, forces in N.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

from protocol_runner.errors import InvalidInput


@dataclass(frozen=True)
class BraceSetup:
    """How the operator has set up the knee brace (thesis §4.1, Appendix A) before fitting it.

    rom_deg: the range-of-motion screws (lo, hi) in degrees: R1 = (40, 90), R2 = (20, 110), R3 = (0, 130),
        R-E = (0, 110).
    friction_nm: the brake's friction torque: level 0/1/2/3 = 0, 1.25, 3.75, 6.25 N·m.
    stiffness_n_per_mm: the spring constant: K0 = 0 (no springs), K1 = 4.4, K2 = 13, K3 = 20 N/mm.
    preload_position: the preload screw position n of Eq 17, 1 (most preload) .. 5 (least); 3 = centre.
    """

    rom_deg: tuple[float, float]
    friction_nm: float
    stiffness_n_per_mm: float
    preload_position: int = 3

    def __post_init__(self) -> None:
        if len(self.rom_deg) != 2:
            raise InvalidInput(f"brace rom_deg must be two angles (lo, hi), got {self.rom_deg!r}")
        lo, hi = (float(v) for v in self.rom_deg)
        if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
            raise InvalidInput(f"brace rom_deg must be two finite angles with hi > lo, got {self.rom_deg!r}")
        if not (math.isfinite(self.friction_nm) and self.friction_nm >= 0.0):
            raise InvalidInput(f"brace friction_nm must be a finite value >= 0, got {self.friction_nm!r}")
        if not (math.isfinite(self.stiffness_n_per_mm) and self.stiffness_n_per_mm >= 0.0):
            raise InvalidInput(
                f"brace stiffness_n_per_mm must be a finite value >= 0, got {self.stiffness_n_per_mm!r}"
            )
        if isinstance(self.preload_position, bool) or self.preload_position not in (1, 2, 3, 4, 5):
            raise InvalidInput(
                f"brace preload_position must be an integer 1-5 (1 = most preload), got {self.preload_position!r}"
            )


@dataclass(frozen=True)
class SimulatorParams:
    """The rig model's constants (see the module docstring; docs/simulator.md has the same table)."""

    # --- integration -------------------------------------------------------------------------------------
    plant_step_s: float = 0.0005
    """Fixed integration step (2 kHz). Half the 1 kHz scan period, so that the stiff range-of-motion stops
    (`rom_stop_stiffness_nm_per_deg`) integrate stably with explicit Euler; samples are taken on this grid."""

    # --- the robot joint: hydraulic position servo (thesis §2.2, §2.4.2) ---------------------------------
    lag_time_constant_s: float = 0.17
    """Time constant of the unloaded servo (first-order lag, valve flow proportional to position error).
    The thesis measured 0.2 s on the loaded joint (§2.4.2, Figures 18-19); the shank's weight slows the
    45° calibration step (20° -> 65°) through the valve law below, so 0.17 s unloaded gives the measured
    0.2 s on that step (tests/hardware/test_simulator.py fits it)."""

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
    gravity_torque_max_nm: float = 35.5
    """m·g·l of the shank (shank + ankle actuators + foot), the torque at 90° of flexion. Chosen: 10 kg
    with its centre of mass 0.36 m below the knee. It pins §5.2 "the robot is unable to reach angles greater
    than 110° [with K2] since the torque limit is reached", together with the spring model of Eq 13-18 and
    the friction: 35.5 sin(110°) + 43.4 (K2, centre preload) + brake and robot friction near rest (≈ 8 N·m
    at level 2) ≈ 84.8 N·m. With it the simulated K2 / R3 / level-2 joint tops out near 107° and the R1 stop
    lets it reach 25-103° (thesis: 25-105°)."""

    gravity_zero_angle_deg: float = 0.0
    """Joint angle at which the shank hangs vertically (no gravity torque). The RSST stands (§2.2), so the
    straight knee (0°) hangs; gravity torque = gravity_torque_max_nm · sin(angle - this)."""

    robot_friction_nm: float = 2.5
    """Coulomb friction of the robot's own actuator and seals (a Dahl hysteresis state). Chosen: thesis §5
    says every graph shows hysteresis that is "an artifact of the robot"; a few N·m is what the brace-off
    loops need to show a visible loop against the 0.8 N·m torque noise."""

    robot_friction_transition_deg: float = 1.5
    """Displacement over which the robot's friction state relaxes to a new direction (Dahl σ = F / this).
    Chosen: gives rounded loop corners as in the thesis's hysteresis plots (Appendix B)."""

    robot_viscous_nm_per_deg_s: float = 0.03
    """Viscous friction of the actuator (hydraulic fluid): 1.5 N·m at the 50 deg/s full speed. Chosen."""

    # --- the brace (thesis §4.1, Appendix A) -------------------------------------------------------------
    brace_pivot_friction_nm: float = 0.75
    """Friction of the brace's hinge with no brake pads (friction level 0). Thesis §5.3: "even for the
    smallest friction value (no brake pads) the area of the graph still is greater than Schmidt's EMU
    data". Added to the brake's level torque."""

    brake_friction_transition_deg: float = 2.0
    """Dahl transition displacement of the brake pads (σ = F / this). Chosen, like the robot's."""

    brake_static_excess: float = 0.3
    """Stribeck effect of the pads: friction at low sliding speed is (1 + this) × the level's torque,
    falling to the level's torque at speeds well above `brake_stribeck_speed_deg_s`. Typical of dry pads;
    it pins §5.7.2 "the energy loss decreases with the speed of the trajectory" (25 vs 50 deg/s)."""

    brake_stribeck_speed_deg_s: float = 20.0
    """Speed scale of the Stribeck effect: F(v) = F·(1 + excess·exp(-(v / this)²)). Chosen between the
    half (25 deg/s) and full (50 deg/s) peak speeds of Appendix A so that the two speeds differ."""

    rom_slack_deg: float = 13.0
    """Misalignment slack at each range-of-motion stop (§5.2): past a stop the brace's lower cuff slides
    along the calf for this many degrees of joint rotation before its travel ends. Pins "when the range was
    limited to [40°, 90°], actual output ranged from [25°, 105°]"."""

    rom_slack_stiffness_nm_per_deg: float = 0.05
    """Resistance while the cuff slides in the slack (straps and foam). Small: at the upper end the robot is
    already within a few N·m of its limit (gravity + K2), and the thesis still saw ~105°."""

    rom_stop_stiffness_nm_per_deg: float = 40.0
    """Stiffness once the slack is used up (saddle extension + hose clamp, §4.2): stiff, but compliant
    enough that the joint stalls a couple of degrees further in, where stop + loads reach the limit."""

    bump_angle_deg: float = 35.0
    """Centre of the low-angle instability "bump" (§5.1: "less than approximately 40°", §5.4: "around
    40°"): the brace shifts on the leg when its springs hold it loosely."""

    bump_width_deg: float = 5.0
    """Gaussian half-width of the bump in angle. Chosen."""

    bump_torque_nm: float = 5.0
    """Bump height with no spring force at `bump_reference_speed_deg_s`. It scales with joint speed (§5.1:
    "enhanced by the higher speed") and with F_ref / (F_ref + spring force at the bump angle), so stiffer
    springs and more preload shrink it (§5.4, §5.5). It pushes the same way on both branches, so it shapes
    the loop without changing the energy lost per cycle."""

    bump_reference_speed_deg_s: float = 50.0
    """Speed at which the bump has its nominal height: the full speed of Appendix A."""

    bump_reference_force_n: float = 200.0
    """Spring force at which the bump is halved. Chosen: K2 at the centre preload pulls ~330 N at 35°."""

    spring_table_step_deg: float = 0.25
    """Resolution of the precomputed spring torque-vs-angle table (Eq 13-18 evaluated by
    protocol_runner.models.spring, linearly interpolated in the integrator). Below 0.01 N·m error."""

    # --- sensors (thesis §2.2, §3.2) ---------------------------------------------------------------------
    angle_noise_deg: float = 0.1
    """White noise on the potentiometer telemetry, 1σ. About 3 LSB of the 12-bit DT9814 on the knee's
    0-130° range. Chosen."""

    torque_noise_nm: float = 0.8
    """White noise on the load-cell telemetry, 1σ. Thesis §3.2: "the data output from the robot is very
    noisy" — the torque needs the 10th-order Butterworth filter of §4.4. Chosen."""

    idle_channel_noise_v: float = 0.005
    """Noise on scanned channels that carry no simulated signal (about 1 LSB)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, int | float) and math.isfinite(value)):
                raise InvalidInput(f"simulator parameter {f.name} must be a finite number, got {value!r}")
            if value < 0.0 and f.name != "gravity_zero_angle_deg":
                raise InvalidInput(f"simulator parameter {f.name} must be >= 0, got {value!r}")
        for name in ("plant_step_s", "lag_time_constant_s", "bump_width_deg", "spring_table_step_deg"):
            if getattr(self, name) <= 0.0:
                raise InvalidInput(f"simulator parameter {name} must be > 0, got {getattr(self, name)!r}")


DEFAULT_PARAMS = SimulatorParams()
"""The documented defaults."""
