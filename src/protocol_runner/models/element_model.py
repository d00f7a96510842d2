"""The device's elements as a physical model of a measured loop: the torque every declared element gives
along a recorded motion, elastic and dissipative alike.

The torque at each sample of a trial (angle θ, speed v from the sample times) is

    τ = Σ angle-only torques (elastic elements, masses' gravity)  +  range-of-motion stops
        + F  (one Dahl friction state for all Coulomb brakes together)  +  c · v  (all dampers together)

with every equation from :mod:`.element_torques`. The brakes act on one hinge and slide together, so the
loop only shows the *sum* of their friction torques: the model has one friction term, named after every
brake it stands for ("brake+hinge"), whose level is the sum of their torques and whose transition and
Stribeck excess are the torque-weighted means of theirs (the simulator's shared state when they share
their smoothing, as the campaigns declare). The dampers are summed likewise. The simulator-tuned cuff
shift (kind "artefact") has no physical counterpart and is left out.

A :class:`ModelLayout` says which parameters are free: each elastic element's `fit` list (as the elastic
fit), the friction sum's torque and transition, the damper sum's coefficient; `values` maps
(element, parameter) to a number for the torque functions.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from numba import njit

from .element_torques import has_static_torque, static_torque_nm
from .element_types import ELEMENT_TYPES
from .elements import Element

FloatArray = npt.NDArray[np.float64]
Key = tuple[str, str]  # (element, parameter)

FRICTION_PARAMS = ("torque_nm", "transition_deg")
DAMPER_PARAM = "damping_nm_s_per_deg"
SETTLE_DEG = 5.0  # travel at a trial's start left out of the fit (`Motion.settled`)


@njit(cache=True)
def dahl_friction_nm(
    angle_deg: FloatArray,
    speed_deg_s: FloatArray,
    torque_nm: float,
    transition_deg: float,
    excess_ratio: float,
    stribeck_speed_deg_s: float,
) -> FloatArray:
    """The Dahl friction torque along a sampled motion (`element_torques.dahl_update` between samples,
    level with the Stribeck excess at each sample's speed), started sliding in the first move's sense."""
    n = angle_deg.shape[0]
    out = np.zeros(n)
    if n == 0 or torque_nm <= 0.0:
        return out
    z = 0.0
    for i in range(1, n):
        if angle_deg[i] != angle_deg[0]:
            z = torque_nm if angle_deg[i] > angle_deg[0] else -torque_nm
            break
    out[0] = z
    for i in range(1, n):
        step = angle_deg[i] - angle_deg[i - 1]
        vs = speed_deg_s[i] / stribeck_speed_deg_s
        level = torque_nm * (1.0 + excess_ratio * math.exp(-vs * vs))
        if step != 0.0:
            target = level if step > 0.0 else -level
            z = target + (z - target) * math.exp(-abs(step) / transition_deg)
        out[i] = z
    return out


def stops_torque_nm(e: Element, angle_deg: FloatArray) -> FloatArray:
    """A `rom_stops` element's torque at each angle (`element_torques.rom_stops_torque_nm`, vectorised)."""
    lo, hi = e.pair("range_deg")
    slack, slack_k, stop_k = (
        e.number("slack_deg"),
        e.number("slack_stiffness_nm_per_deg"),
        e.number("stop_stiffness_nm_per_deg"),
    )

    def one(pen: FloatArray) -> FloatArray:
        pen = np.maximum(pen, 0.0)
        return np.where(pen <= slack, slack_k * pen, slack_k * slack + stop_k * (pen - slack))

    return one(angle_deg - hi) - one(lo - angle_deg)


@dataclass(frozen=True)
class Motion:
    """One trial's motion and measured torque, in sample order. `settled`: the first sample the fit
    compares (after SETTLE_DEG of travel: the friction state at a trial's start is unknown, and the
    filtered loop's first samples carry the filter's edge)."""

    angle_deg: FloatArray
    speed_deg_s: FloatArray
    torque_nm: FloatArray
    settled: int = 0

    @staticmethod
    def from_samples(time_s: npt.ArrayLike, angle_deg: npt.ArrayLike, torque_nm: npt.ArrayLike) -> Motion:
        t = np.asarray(time_s, dtype=np.float64)
        a = np.asarray(angle_deg, dtype=np.float64)
        y = np.asarray(torque_nm, dtype=np.float64)
        keep = np.isfinite(t) & np.isfinite(a) & np.isfinite(y)
        t, a, y = t[keep], a[keep], y[keep]
        v = np.gradient(a, t) if a.size >= 2 else np.zeros_like(a)
        travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(a)))])
        settled = int(np.searchsorted(travel, SETTLE_DEG))
        return Motion(a, v, y, settled if settled < a.size - 2 else 0)

    def decimated(self, max_step_deg: float = 1.0) -> Motion:
        """Every k-th sample, k the largest keeping the median step within `max_step_deg` (the Dahl update
        is exact over any monotone step, so a coarser sampling of a smooth motion changes little)."""
        steps = np.abs(np.diff(self.angle_deg))
        median = float(np.median(steps)) if steps.size else 0.0
        k = max(1, int(max_step_deg / median)) if median > 0 else 1
        if k == 1:
            return self
        return Motion(self.angle_deg[::k], self.speed_deg_s[::k], self.torque_nm[::k], -(-self.settled // k))


@dataclass(frozen=True)
class ModelLayout:
    """The element model of one device: its elements, how the brakes and dampers are summed, and the
    free parameters (`free`, (element, parameter) pairs; the friction and damper sums under their
    joined names)."""

    elements: tuple[Element, ...]
    friction_name: str  # "" when the device has no brake
    friction_members: tuple[str, ...]
    damper_name: str
    damper_members: tuple[str, ...]
    free: tuple[Key, ...]
    declared: Mapping[Key, float]  # the device's value of every free parameter (sums for the friction/damper)
    excess_ratio: float
    stribeck_speed_deg_s: float

    def values(self, x: Sequence[float] | FloatArray) -> dict[Key, float]:
        out = dict(self.declared)
        out.update(zip(self.free, (float(v) for v in x), strict=True))
        return out


def _joined(elements: Sequence[Element]) -> str:
    return "+".join(e.name for e in elements)


def layout(
    elements: Sequence[Element],
    *,
    dissipative: bool = True,
    elastic_free: bool = True,
    angle_deg: FloatArray | None = None,
) -> ModelLayout:
    """The element model of `elements`. `dissipative` False: the brakes' and dampers' declared values are
    kept (not free). `elastic_free` False: the elastic elements keep their values. An elastic element
    that gives no torque over `angle_deg` (a spring of stiffness 0) has nothing to fit and stays fixed."""
    elements = tuple(e for e in elements if e.kind != "artefact")
    brakes = [e for e in elements if e.type == "coulomb_brake"]
    dampers = [e for e in elements if e.type == "viscous_damper"]
    free: list[Key] = []
    declared: dict[Key, float] = {}
    probe = np.linspace(np.min(angle_deg), np.max(angle_deg), 64) if angle_deg is not None else None
    if elastic_free:
        for e in elements:
            if e.kind != "elastic":
                continue
            if probe is not None and not np.any(static_torque_nm(e, probe) != 0.0):
                continue
            for p in e.fit:
                free.append((e.name, p))
                declared[(e.name, p)] = e.number(p)
    fname = _joined(brakes)
    total = sum(b.number("torque_nm") for b in brakes)
    weights = [b.number("torque_nm") / total if total > 0 else 1.0 / len(brakes) for b in brakes]

    def mean(p: str) -> float:
        return float(sum(w * b.number(p) for w, b in zip(weights, brakes, strict=True)))

    if brakes:
        declared[(fname, "torque_nm")] = float(total)
        declared[(fname, "transition_deg")] = mean("transition_deg")
        if dissipative:
            free += [(fname, p) for p in FRICTION_PARAMS]
    dname = _joined(dampers)
    if dampers:
        declared[(dname, DAMPER_PARAM)] = float(sum(d.number(DAMPER_PARAM) for d in dampers))
        if dissipative:
            free.append((dname, DAMPER_PARAM))
    return ModelLayout(
        elements=elements,
        friction_name=fname,
        friction_members=tuple(b.name for b in brakes),
        damper_name=dname,
        damper_members=tuple(d.name for d in dampers),
        free=tuple(free),
        declared=declared,
        excess_ratio=mean("static_excess_ratio") if brakes else 0.0,
        stribeck_speed_deg_s=mean("stribeck_speed_deg_s") if brakes else 1.0,
    )


def param_spec_key(lay: ModelLayout, key: Key) -> tuple[str, str]:
    """(element type, parameter) of a free parameter, for its registry entry."""
    name, param = key
    if name == lay.friction_name and lay.friction_members:
        return "coulomb_brake", param
    if name == lay.damper_name and lay.damper_members:
        return "viscous_damper", param
    etype = next(e.type for e in lay.elements if e.name == name)
    return etype, param


def elastic_torque_nm(lay: ModelLayout, values: Mapping[Key, float], angle_deg: FloatArray) -> FloatArray:
    """The angle-only torques (elastic elements with `values`, masses) and the stops at each angle."""
    total = np.zeros(angle_deg.shape, dtype=np.float64)
    for e in lay.elements:
        if has_static_torque(e):
            changed = {p: values[(e.name, p)] for p in e.fit if (e.name, p) in values}
            total += static_torque_nm(e.replace(**changed) if changed else e, angle_deg)
        elif e.type == "rom_stops":
            total += stops_torque_nm(e, angle_deg)
    return total


def model_torque_nm(
    lay: ModelLayout, values: Mapping[Key, float], motion: Motion, *, friction: bool = True
) -> FloatArray:
    """The model's torque at every sample of `motion` (module docstring)."""
    torque = elastic_torque_nm(lay, values, motion.angle_deg)
    if friction and lay.friction_members:
        torque += dahl_friction_nm(
            motion.angle_deg,
            motion.speed_deg_s,
            max(values[(lay.friction_name, "torque_nm")], 0.0),
            max(values[(lay.friction_name, "transition_deg")], 1e-6),
            lay.excess_ratio,
            lay.stribeck_speed_deg_s,
        )
    if lay.damper_members:
        torque += values[(lay.damper_name, DAMPER_PARAM)] * motion.speed_deg_s
    return torque


MULTIPLICATIVE_UNITS = ("_nm", "_n_per_mm", "_nm_per_deg", "_nm_s_per_deg")


def transfer(lay_a: ModelLayout, lay_b: ModelLayout, fitted_a: Mapping[Key, float]) -> dict[Key, float]:
    """Configuration B's parameter values from A's fitted ones and the declared change A -> B.

    A parameter declared equal in A and B keeps A's fitted value. One that differs takes the declared
    factor (a torque, stiffness or damping: fitted_A · declared_B / declared_A) or the declared shift
    (an angle or a length: fitted_A + declared_B - declared_A). A parameter of B with no counterpart in A
    keeps B's declared value."""
    out = dict(lay_b.declared)
    for key, b_value in lay_b.declared.items():
        if key not in fitted_a or key not in lay_a.declared:
            continue
        a_value = lay_a.declared[key]
        fit = fitted_a[key]
        if a_value == b_value:
            out[key] = fit
            continue
        etype, param = param_spec_key(lay_b, key)
        unit = ELEMENT_TYPES[etype].parameters[param].unit
        if unit in MULTIPLICATIVE_UNITS and a_value != 0.0:
            out[key] = fit * b_value / a_value
        else:
            out[key] = fit + b_value - a_value
    return out
