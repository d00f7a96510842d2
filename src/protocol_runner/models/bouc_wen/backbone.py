"""The elastic backbone of a joint's loop: ``torque = g(angle) + z`` (docs/analysis.md §9, "Backbone plus
hysteresis").

The elastic part is a smooth function of the angle alone, fitted first, and the Bouc-Wen state describes
what is left (the thesis's ``torque = z`` forces a spring and a brake into one hysteresis). By default ``g``
is a polynomial of ``u = angle / angle_scale`` (degree 9: it follows range-of-motion stops) fitted by least
squares to every sample: the loop's midline, which encloses no energy, so all the loss stays in ``z``. A
:class:`FixedBackbone` is a ``g`` given from outside (the device's elastic elements), held fixed; a
:data:`BackboneFactory` builds one from the indices of the trials a fit may use, so that a held-out trial
never enters its own backbone.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

from .params import FloatArray

MAX_DEGREE = 15


@dataclass(frozen=True)
class Backbone:
    """``g(x) = sum_k coef[k] (x / angle_scale_deg)^k`` in N*m (x in degrees)."""

    coef: tuple[float, ...]
    angle_scale_deg: float

    def __call__(self, angle_deg: npt.ArrayLike) -> FloatArray:
        """g at the given angles; beyond the fitted range (|u| > 1) continued along its end tangent, so
        that a prediction on a wider range does not follow the polynomial's runaway."""
        u = np.asarray(angle_deg, dtype=np.float64) / self.angle_scale_deg
        poly = np.polynomial.polynomial
        inside = np.clip(u, -1.0, 1.0)
        value = poly.polyval(inside, self.coef)
        slope = poly.polyval(inside, poly.polyder(self.coef)) if len(self.coef) > 1 else 0.0
        return np.asarray(value + slope * (u - inside), dtype=np.float64)

    @property
    def degree(self) -> int:
        return len(self.coef) - 1


@dataclass(frozen=True)
class FixedBackbone:
    """``g(x) = torque_nm(x)`` in N*m (x in degrees), given rather than fitted here.

    kind: what ``g`` is, as recorded in the archive ("elements"; "none" when ``g`` is identically zero,
    e.g. a device with no elastic element); note: one line saying where ``g`` comes from or why it is zero."""

    torque_nm: Callable[[npt.NDArray[np.float64]], npt.ArrayLike]
    kind: str = "elements"
    note: str = ""

    def __call__(self, angle_deg: npt.ArrayLike) -> FloatArray:
        x = np.asarray(angle_deg, dtype=np.float64)
        return np.ascontiguousarray(np.broadcast_to(np.asarray(self.torque_nm(x), dtype=np.float64), x.shape))


def zero_backbone(note: str) -> FixedBackbone:
    """``g = 0`` (the thesis form torque = z), with the reason recorded."""
    return FixedBackbone(torque_nm=lambda x: np.zeros_like(x), kind="none", note=note)


# the backbone of a fit on the trials with these indices (0-based, into the fit's list of trials)
BackboneFactory = Callable[[Sequence[int]], FixedBackbone]
AnyBackbone = Backbone | FixedBackbone


def fit_backbone(segments: Sequence[tuple[FloatArray, FloatArray]], degree: int = 9) -> Backbone:
    """Least-squares polynomial of the angle through every sample of every trial (the loops' midline)."""
    if not (isinstance(degree, int) and 0 <= degree <= MAX_DEGREE):
        raise InvalidInput(f"backbone degree must be an integer from 0 to {MAX_DEGREE}, got {degree!r}")
    x = np.concatenate([np.asarray(s[0], dtype=np.float64) for s in segments])
    y = np.concatenate([np.asarray(s[1], dtype=np.float64) for s in segments])
    scale = float(np.max(np.abs(x))) if x.size else 0.0
    if not (scale > 0.0 and math.isfinite(scale)):
        raise InvalidInput("the angle is zero everywhere: no backbone can be fitted")
    V = np.polynomial.polynomial.polyvander(x / scale, degree)
    coef, *_ = np.linalg.lstsq(V, y, rcond=None)
    return Backbone(coef=tuple(float(c) for c in coef), angle_scale_deg=scale)


def hysteretic_part(
    segments: Sequence[tuple[FloatArray, FloatArray]], backbone: Backbone | FixedBackbone
) -> list[tuple[FloatArray, FloatArray]]:
    """Each trial's torque minus the backbone: what the Bouc-Wen state has to describe."""
    return [(x, np.ascontiguousarray(y - backbone(x))) for x, y in segments]
