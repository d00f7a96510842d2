"""Each device element's torque equation, once (the element types are in `models.elements`).

Used by the DAQ simulator (the angle-only torques tabulated into its plant, the others called from its
compiled kernel, hence `@njit`) and by the element fit (`analysis.element_fit`). Angles in degrees, speeds
in deg/s, torques in N·m; a positive torque is what the robot must apply towards +angle (`models.spring`).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt
from numba import njit

from protocol_runner.models.elements import Element
from protocol_runner.models.spring import SpringGeometry, spring_force_n, spring_torque_nm
from protocol_runner.numba_cache import cache_enabled

CACHE = cache_enabled()  # numba caches on disk unless no directory is writable (numba_cache.py)

FloatArray = npt.NDArray[np.float64]

STANDARD_GRAVITY_M_S2 = 9.80665


# --- elastic elements (torque depends on the angle only) ----------------------------------------------------
def lever_geometry(e: Element) -> SpringGeometry:
    """The `lever_spring` element's Eq 15-17 geometry."""
    return SpringGeometry(
        a_m=e.number("a_m"),
        b_m=e.number("b_m"),
        c_m=e.number("c_m"),
        alpha_deg=e.number("alpha_deg"),
        preload_step_deg=e.number("preload_step_deg"),
        n_springs=int(e.number("count")),
    )


def lever_spring_force_n(angle_deg: float, e: Element) -> float:
    """Tension of one of the element's springs at `angle_deg` (Eq 14)."""
    force = spring_force_n(
        angle_deg - e.number("zero_offset_deg"),
        e.number("stiffness_n_per_mm"),
        e.number("preload_index"),
        max_preload_mm=e.number("max_preload_mm"),
        geometry=lever_geometry(e),
    )
    return float(force)


def static_torque_nm(e: Element, angle_deg: npt.ArrayLike) -> FloatArray:
    """The torque of an element that depends on the angle alone: elastic elements and a mass's gravity.
    What the simulator tabulates and the element fit models.

    lever_spring: Eq 13-18 (`models.spring.spring_torque_nm`) with the element's stiffness, screw position,
    Max_Preload, zero offset and geometry; torsion_spring: k·(θ - θ_neutral); bungee, tension only:
    k·(θ - θ_slack) where direction·(θ - θ_slack) > 0, else zero; mass: m·g·l·sin(θ - θ_hanging), zero where
    it hangs."""
    x = np.asarray(angle_deg, dtype=np.float64)
    num = e.number
    if e.type == "lever_spring":
        return spring_torque_nm(
            x,
            num("stiffness_n_per_mm"),
            num("preload_index"),
            max_preload_mm=num("max_preload_mm"),
            zero_offset_deg=num("zero_offset_deg"),
            geometry=lever_geometry(e),
        )
    if e.type == "torsion_spring":
        return num("stiffness_nm_per_deg") * (x - num("neutral_deg"))
    if e.type == "bungee":
        stretch = x - num("slack_deg")
        return np.where(num("direction") * stretch > 0.0, num("stiffness_nm_per_deg") * stretch, 0.0)
    if e.type == "mass":
        weight_nm = num("mass_kg") * STANDARD_GRAVITY_M_S2 * num("lever_m")
        return weight_nm * np.sin(np.radians(x - num("hanging_deg")))
    raise ValueError(f"element {e.name!r} ({e.type}) has no angle-only torque")


def has_static_torque(e: Element) -> bool:
    """Whether `static_torque_nm` applies (elastic elements and masses)."""
    return e.kind == "elastic" or e.type == "mass"


# --- compiled equations the simulator's kernel calls -------------------------------------------------------
@njit(cache=CACHE)
def dahl_update(z: float, level: float, step_deg: float, transition_deg: float) -> float:
    """A Coulomb friction state with rounded reversals (Dahl), exactly over a displacement `step_deg`:
    z relaxes towards sign(step)·level with e-folding travel `transition_deg` (σ = level / transition)."""
    if level <= 0.0:
        return 0.0
    if step_deg == 0.0:
        return z
    target = level if step_deg > 0.0 else -level
    return target + (z - target) * math.exp(-abs(step_deg) / transition_deg)


@njit(cache=CACHE)
def stribeck_level_nm(
    torque_nm: float, speed_deg_s: float, excess_ratio: float, stribeck_speed_deg_s: float
) -> float:
    """The brake's friction level at a sliding speed: T·(1 + excess·exp(-(v / v_s)²))."""
    vs = speed_deg_s / stribeck_speed_deg_s
    return torque_nm * (1.0 + excess_ratio * math.exp(-vs * vs))


@njit(cache=CACHE)
def viscous_torque_nm(damping_nm_s_per_deg: float, speed_deg_s: float) -> float:
    """A viscous damper: c·dθ/dt."""
    return damping_nm_s_per_deg * speed_deg_s


@njit(cache=CACHE)
def stop_torque_nm(penetration_deg: float, slack_deg: float, slack_k: float, stop_k: float) -> float:
    """One range-of-motion stop penetrated by `penetration_deg` (> 0): soft over the slack, then stiff."""
    if penetration_deg <= slack_deg:
        return slack_k * penetration_deg
    return slack_k * slack_deg + stop_k * (penetration_deg - slack_deg)


@njit(cache=CACHE)
def rom_stops_torque_nm(
    angle_deg: float, lo_deg: float, hi_deg: float, slack_deg: float, slack_k: float, stop_k: float
) -> float:
    """Both stops of a `rom_stops` element: pushes back towards [lo, hi]."""
    torque = 0.0
    if lo_deg - angle_deg > 0.0:
        torque -= stop_torque_nm(lo_deg - angle_deg, slack_deg, slack_k, stop_k)
    if angle_deg - hi_deg > 0.0:
        torque += stop_torque_nm(angle_deg - hi_deg, slack_deg, slack_k, stop_k)
    return torque


@njit(cache=CACHE)
def cuff_shift_torque_nm(
    angle_deg: float,
    speed_deg_s: float,
    centre_deg: float,
    width_deg: float,
    height_nm: float,
    ref_speed_deg_s: float,
) -> float:
    """The simulator-tuned cuff shift: height·min(|v| / v_ref, 3)·exp(-((θ - centre) / width)²), the same
    sign on both branches (it shapes the loop without changing the energy per cycle)."""
    d = (angle_deg - centre_deg) / width_deg
    if d * d >= 30.0:
        return 0.0
    v = min(abs(speed_deg_s) / ref_speed_deg_s, 3.0)
    return height_nm * v * math.exp(-d * d)


def cuff_shift_height_nm(e: Element, lever_springs: list[Element]) -> float:
    """The cuff shift's height for a device: torque_nm · F_ref / (F_ref + the lever springs' force at the
    bump angle) (stiffer springs and more preload hold the brace steadier, thesis §5.4-5.5)."""
    force_n = 0.0
    for spring in lever_springs:
        if spring.number("stiffness_n_per_mm") > 0.0:
            force_n += lever_spring_force_n(e.number("angle_deg"), spring)
    ref = e.number("reference_force_n")
    return e.number("torque_nm") * (ref / (ref + force_n) if ref > 0.0 else 0.0)
