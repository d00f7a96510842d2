"""The registry of element types of a device under test and their parameters (name, unit suffix, default,
fittable, allowed interval): what the protocol loader checks a campaign file against, the simulator composes
and the element fit may estimate. Elements are built in :mod:`.elements`; each type's torque equation lives
in :mod:`.element_torques`; docs/protocol.md and docs/simulator.md describe the types for a test engineer.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import KW_ONLY, dataclass
from typing import Literal

ElementKind = Literal["elastic", "dissipative", "stop", "inertial", "artefact"]
Shape = Literal["number", "pair", "integer", "sign", "names"]


@dataclass(frozen=True)
class ParamSpec:
    """One parameter of an element type.

    unit: the unit suffix a binding's quantity must carry ("_nm", "_deg", ...; "" for a bare number such as
    a sign or a list of names). default: the value when the protocol omits it; None = required.
    fittable: the element fit may estimate it. bounds: the allowed closed interval (for a fittable parameter
    also the fit's search interval); None = any finite value. shape: a number, a [lo, hi] pair, an integer,
    a sign (+1 / -1) or a list of parameter names. fit_starts / fit_scale: the fit's starting values (besides
    the declared value) and its parameter scale (scipy `least_squares` x_scale).
    """

    unit: str
    doc: str
    default: float | str | None = None
    _: KW_ONLY
    fittable: bool = False
    bounds: tuple[float, float] | None = None
    shape: Shape = "number"
    fit_starts: tuple[float, ...] = ()
    fit_scale: float = 1.0
    plausible: tuple[float, float] | None = None


@dataclass(frozen=True)
class ElementType:
    """An element type: its name, what it models, its kind and its parameters.

    kind: "elastic" (a torque that depends on the angle only: summed into the simulator's angle table, and
    what the element fit estimates), "dissipative" (brakes and dampers), "stop" (range-of-motion stops),
    "inertial" (a mass: gravity and inertia), "artefact" (a simulator-tuned effect with no physical
    counterpart to measure). default_fit: the parameters the element fit estimates when the element's
    `fit` parameter is not given.
    """

    name: str
    doc: str
    kind: ElementKind
    parameters: Mapping[str, ParamSpec]
    default_fit: tuple[str, ...] = ()


def _fit_param(default_fit: tuple[str, ...]) -> ParamSpec:
    return ParamSpec(
        "",
        "the parameters the element fit estimates (a list of this element's fittable parameter names); "
        f"default {', '.join(default_fit)}",
        ",".join(default_fit),
        shape="names",
    )


_NONNEG = (0.0, math.inf)

_LEVER_FIT = ("max_preload_mm", "zero_offset_deg")
_TORSION_FIT = ("stiffness_nm_per_deg", "neutral_deg")
_BUNGEE_FIT = ("stiffness_nm_per_deg", "slack_deg")

ELEMENT_TYPES: Mapping[str, ElementType] = {
    t.name: t
    for t in (
        ElementType(
            "lever_spring",
            "extension springs between a fixed attachment at distance a from the axis (angle alpha from the "
            "reference) and an attachment turning with the joint at radius a + b, preloaded by a screw "
            "(thesis §6.1, Eq 13-18): zero torque at alpha + zero_offset_deg, growing on both sides",
            "elastic",
            {
                "stiffness_n_per_mm": ParamSpec(
                    "_n_per_mm", "spring constant K of one spring (Eq 14); 0 = no spring", bounds=(0.0, 1e4)
                ),
                "preload_index": ParamSpec(
                    "_index",
                    "preload screw position n of Eq 17 (0 = Max_Preload; each step lowers the preload)",
                    0.0,
                    bounds=(0.0, 1e3),
                    shape="integer",
                ),
                "max_preload_mm": ParamSpec(
                    "_mm",
                    "Max_Preload of Eq 17: spring extension at screw position 0",
                    fittable=True,
                    bounds=(0.0, 100.0),
                    fit_starts=(10.0, 60.0),
                    fit_scale=10.0,
                    plausible=(0.0, 100.0),
                ),
                "zero_offset_deg": ParamSpec(
                    "_deg",
                    "shift of the zero-torque angle from alpha (thesis §6.1.6: it moves with the springs)",
                    0.0,
                    fittable=True,
                    bounds=(-40.0, 40.0),
                    fit_starts=(-15.0, 15.0),
                    fit_scale=10.0,
                    plausible=(-40.0, 40.0),
                ),
                "a_m": ParamSpec(
                    "_m",
                    "distance from the axis to the fixed (upper) attachment (Eq 15)",
                    bounds=(1e-9, 10.0),
                ),
                "b_m": ParamSpec(
                    "_m", "spring length at the zero-torque angle (Eq 15-16)", bounds=(1e-9, 10.0)
                ),
                "c_m": ParamSpec("_m", "lever of the preload piece (Eq 17)", 0.0, bounds=(0.0, 10.0)),
                "alpha_deg": ParamSpec(
                    "_deg", "angle of the fixed attachment: the zero-torque angle (Eq 13, 15)"
                ),
                "preload_step_deg": ParamSpec(
                    "_deg", "angle between two preload screw positions (Eq 17)", 0.0
                ),
                "count": ParamSpec(
                    "_count",
                    "springs in parallel (the factor 2 of Eq 13)",
                    1.0,
                    bounds=(0.0, 100.0),
                    shape="integer",
                ),
                "fit": _fit_param(_LEVER_FIT),
            },
            _LEVER_FIT,
        ),
        ElementType(
            "torsion_spring",
            "a linear torsion spring: torque = stiffness · (angle - neutral)",
            "elastic",
            {
                "stiffness_nm_per_deg": ParamSpec(
                    "_nm_per_deg", "torsional stiffness", fittable=True, bounds=(0.0, 1e4)
                ),
                "neutral_deg": ParamSpec(
                    "_deg", "angle of zero torque", fittable=True, bounds=(-720.0, 720.0), fit_scale=10.0
                ),
                "fit": _fit_param(_TORSION_FIT),
            },
            _TORSION_FIT,
        ),
        ElementType(
            "bungee",
            "an elastic cord: pulls only when taut. direction +1: taut above slack_deg, torque = stiffness · "
            "(angle - slack_deg) there; -1: taut below slack_deg; zero torque on the slack side",
            "elastic",
            {
                "stiffness_nm_per_deg": ParamSpec(
                    "_nm_per_deg", "stiffness when taut", fittable=True, bounds=(0.0, 1e4)
                ),
                "slack_deg": ParamSpec(
                    "_deg",
                    "angle at which the cord becomes taut",
                    fittable=True,
                    bounds=(-720.0, 720.0),
                    fit_scale=10.0,
                ),
                "direction": ParamSpec("", "+1: taut above slack_deg; -1: taut below it", 1.0, shape="sign"),
                "fit": _fit_param(_BUNGEE_FIT),
            },
            _BUNGEE_FIT,
        ),
        ElementType(
            "coulomb_brake",
            "dry friction of constant level with rounded reversals (a Dahl state: the torque relaxes to "
            "±level over transition_deg of travel) and a Stribeck excess at low sliding speed: level = "
            "torque · (1 + static_excess_ratio · exp(-(speed / stribeck_speed)²)). Loses "
            "4·T·(A − x0·(1 − exp(−2A/x0))) per cycle of amplitude A (x0 the transition, both in rad): "
            "4·T·A less the rounded reversals. Brakes with equal smoothing share one state in the simulator",
            "dissipative",
            {
                "torque_nm": ParamSpec("_nm", "friction torque while sliding fast", bounds=_NONNEG),
                "transition_deg": ParamSpec(
                    "_deg",
                    "travel over which the friction reverses (Dahl σ = torque / this)",
                    1.0,
                    bounds=(1e-6, 90.0),
                    plausible=(0.01, 30.0),
                ),
                "static_excess_ratio": ParamSpec(
                    "_ratio",
                    "friction excess at standstill, as a fraction of torque_nm",
                    0.0,
                    bounds=(0.0, 10.0),
                ),
                "stribeck_speed_deg_s": ParamSpec(
                    "_deg_s", "speed scale of the Stribeck excess", 10.0, bounds=(1e-6, 1e4)
                ),
            },
        ),
        ElementType(
            "viscous_damper",
            "viscous damping: torque = damping · speed. Loses π·c·ω·A² per cycle (c per rad)",
            "dissipative",
            {"damping_nm_s_per_deg": ParamSpec("_nm_s_per_deg", "damping coefficient", bounds=_NONNEG)},
        ),
        ElementType(
            "rom_stops",
            "range-of-motion stops: beyond either end of range_deg the device first gives slack_deg of soft "
            "travel (a misaligned cuff sliding, thesis §5.2), then is stiff",
            "stop",
            {
                "range_deg": ParamSpec("_deg", "the stops [lo, hi]", shape="pair"),
                "slack_deg": ParamSpec("_deg", "soft travel past each stop", 0.0, bounds=(0.0, 360.0)),
                "slack_stiffness_nm_per_deg": ParamSpec(
                    "_nm_per_deg", "stiffness within the slack", 0.0, bounds=_NONNEG
                ),
                "stop_stiffness_nm_per_deg": ParamSpec(
                    "_nm_per_deg", "stiffness once the slack is used", bounds=_NONNEG
                ),
            },
        ),
        ElementType(
            "mass",
            "a point mass on a lever turning with the joint: gravity torque m·g·l·sin(angle - hanging_deg) "
            "(zero where it hangs) and inertia m·l²",
            "inertial",
            {
                "mass_kg": ParamSpec("_kg", "the mass", bounds=_NONNEG),
                "lever_m": ParamSpec("_m", "distance of its centre of mass from the axis", bounds=_NONNEG),
                "hanging_deg": ParamSpec("_deg", "joint angle at which it hangs straight down", 0.0),
            },
        ),
        ElementType(
            "cuff_shift",
            "SIMULATOR-TUNED artefact: a brace shifting on the leg near angle_deg (thesis §5.1, §5.4) — a "
            "Gaussian torque bump, the same sign on both branches, growing with speed and shrinking as "
            "reference_force_n / (reference_force_n + the lever springs' force at angle_deg)",
            "artefact",
            {
                "angle_deg": ParamSpec("_deg", "centre of the bump"),
                "width_deg": ParamSpec("_deg", "Gaussian half-width", bounds=(1e-6, 360.0)),
                "torque_nm": ParamSpec(
                    "_nm", "height with no spring force at the reference speed", bounds=_NONNEG
                ),
                "reference_speed_deg_s": ParamSpec(
                    "_deg_s", "speed of the nominal height", bounds=(1e-6, 1e4)
                ),
                "reference_force_n": ParamSpec(
                    "_n", "spring force that halves the bump (0: no bump)", bounds=_NONNEG
                ),
            },
        ),
    )
}
"""Every element type, by name."""
