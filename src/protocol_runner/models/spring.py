"""Physical model of the knee brace springs (thesis §6.1, Eq 13-18) — geometry reconstructed here.

The thesis prints Eq 15-16 garbled; the geometry below is a **reconstruction** (derivation and sketch in
docs/hardware-model.md §1) that reproduces every stated fact: the spring is shortest at θ = α = 20°
(Figure 50), its deflection grows on both sides, and the torque of Eq 13 is zero at 20° and grows with
bending (Figure 51). O is the axis, U the upper attachment (|OU| = a, at α from the vertical), A the lower
one (|OA| = r = a + b, at the bending angle θ); at θ = α the spring (length b) lies on the ray OU::

    O = (0, 0),  U = (a cos α, -a sin α),  A = (r cos θ, -r sin θ)        (Eq 15, with r = a + b)
    length L(θ) = |A - U| = sqrt(r² + a² - 2 a r cos(θ - α))
    deflection δ(θ) = L(θ) - b  >= 0, zero at θ = α                        (Eq 16)
    λ = atan2(y_A + a sin α, x_A - a cos α)                                (Eq 18; atan2 for the quadrant)
    T = -n_springs * F * a * sin(λ + α) = n_springs * F * a * r * sin(θ - α) / L     (Eq 13)

Sign convention (docs/hardware-model.md): a positive torque is the torque the robot must apply in the
flexion (+angle) direction; Eq 13 has exactly this sign with the geometry above.

Force (Eq 14): F = K (Initial_Load + δ), K in N/mm, lengths in mm; an extension spring that is slack (only
possible with a preload below zero) pulls with zero force. Initial load (Eq 17): Initial_Load =
Max_Preload - c * preload_angle_step * π/180 * n for screw position n (n = 0 would be the maximum preload).
The knee brace's numbers are the `lever_spring` element's parameters in protocols/knee_phase1.yaml.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

FloatArray = npt.NDArray[np.float64]
ArrayLike = npt.ArrayLike


@dataclass(frozen=True)
class SpringGeometry:
    """Fixed dimensions of the brace's spring mechanism (thesis §6.1.1, Figure 47).

    a_m: distance from the centre of rotation to the spring's upper attachment.
    b_m: undeflected spring length.
    c_m: lever of the preload piece (its pivot to the spring's lower attachment).
    alpha_deg: angle between the vertical and the upper attachment (the zero-torque angle).
    preload_step_deg: angle between two screw positions of the preload piece.
    n_springs: number of springs in parallel (the factor 2 of Eq 13).
    """

    a_m: float
    b_m: float
    c_m: float
    alpha_deg: float
    preload_step_deg: float
    n_springs: int

    def __post_init__(self) -> None:
        for name in ("a_m", "b_m", "c_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and (value > 0.0 or (name == "c_m" and value == 0.0))):
                raise InvalidInput(
                    f"spring geometry: {name} must be a positive length in metres, got {value!r}"
                )
        if not math.isfinite(self.alpha_deg) or not math.isfinite(self.preload_step_deg):
            raise InvalidInput("spring geometry: alpha_deg and preload_step_deg must be finite")
        if self.n_springs < 0:
            raise InvalidInput(f"spring geometry: n_springs must be >= 0, got {self.n_springs}")

    @property
    def lower_radius_m(self) -> float:
        """Radius r = a + b of the circle the lower attachment moves on (reconstructed Eq 15)."""
        return self.a_m + self.b_m

    @property
    def preload_step_m(self) -> float:
        """Change of spring extension per screw position: c * step * π/180 (Eq 17)."""
        return self.c_m * math.radians(self.preload_step_deg)


def _attachment_geometry(
    angle_deg: ArrayLike, geometry: SpringGeometry
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Return (x_A, y_A, L): lower attachment coordinates (Eq 15) and spring length, all in metres."""
    theta = np.radians(np.asarray(angle_deg, dtype=np.float64))
    alpha = math.radians(geometry.alpha_deg)
    r = geometry.lower_radius_m
    a = geometry.a_m
    x_a = r * np.cos(theta)
    y_a = -r * np.sin(theta)
    length = np.hypot(x_a - a * math.cos(alpha), y_a + a * math.sin(alpha))
    return x_a, y_a, length


def spring_initial_load_m(preload_position: float, max_preload_mm: float, geometry: SpringGeometry) -> float:
    """Initial spring extension set by the preload screw (Eq 17), in metres, for screw position n =
    `preload_position` (a whole number >= 0); negative for a small `max_preload_mm` (slack near α)."""
    n = preload_position
    ok = not isinstance(n, bool) and isinstance(n, int | float | np.integer)
    if not ok or n < 0 or n != round(n):
        raise InvalidInput(f"spring preload position must be a whole number >= 0, got {n!r}")
    if not math.isfinite(max_preload_mm):
        raise InvalidInput(f"max_preload_mm must be finite, got {max_preload_mm!r}")
    return max_preload_mm * 1e-3 - geometry.preload_step_m * n


def spring_force_n(
    angle_deg: ArrayLike,
    stiffness_n_per_mm: float,
    preload_position: float,
    *,
    max_preload_mm: float,
    geometry: SpringGeometry,
) -> FloatArray:
    """Tension of one spring at brace angle θ (Eq 14), in newtons; K in N/mm (0 = no spring, K0); an
    extension spring cannot push. Vectorised over `angle_deg`."""
    _check_stiffness(stiffness_n_per_mm)
    _, _, length = _attachment_geometry(angle_deg, geometry)
    return _force_n(stiffness_n_per_mm, preload_position, max_preload_mm, geometry, length)


def _check_stiffness(stiffness_n_per_mm: float) -> None:
    if not (math.isfinite(stiffness_n_per_mm) and stiffness_n_per_mm >= 0.0):
        raise InvalidInput(f"spring stiffness must be a finite value >= 0 N/mm, got {stiffness_n_per_mm!r}")


def _force_n(
    stiffness_n_per_mm: float,
    preload_position: float,
    max_preload_mm: float,
    geometry: SpringGeometry,
    length_m: FloatArray,
) -> FloatArray:
    """Eq 14 from the spring length (`_attachment_geometry`): K (Initial_Load + δ), no push."""
    deflection_m: FloatArray = length_m - geometry.b_m  # Eq 16
    extension_m = spring_initial_load_m(preload_position, max_preload_mm, geometry) + deflection_m
    force: FloatArray = stiffness_n_per_mm * 1e3 * np.maximum(extension_m, 0.0)
    return force


def spring_torque_nm(
    angle_deg: ArrayLike,
    stiffness_n_per_mm: float,
    preload_position: float,
    *,
    max_preload_mm: float,
    geometry: SpringGeometry,
    zero_offset_deg: float = 0.0,
) -> FloatArray:
    """Torque of the brace springs about the joint axis at joint angle `angle_deg` (Eq 13, 14, 18), N·m,
    positive where the robot must push in flexion. The brace angle is θ = angle_deg - zero_offset_deg, so
    the zero-torque angle is α + zero_offset_deg (thesis §6.1.6: it moves when the springs change).
    Stiffness 0 (K0) gives zeros. Vectorised.
    """
    if not math.isfinite(zero_offset_deg):
        raise InvalidInput(f"zero_offset_deg must be finite, got {zero_offset_deg!r}")
    theta_deg = np.asarray(angle_deg, dtype=np.float64) - zero_offset_deg
    _check_stiffness(stiffness_n_per_mm)
    x_a, y_a, length = _attachment_geometry(theta_deg, geometry)  # once: Eq 14's extension and Eq 18's angle
    force = _force_n(stiffness_n_per_mm, preload_position, max_preload_mm, geometry, length)
    alpha = math.radians(geometry.alpha_deg)
    a = geometry.a_m
    lam = np.arctan2(y_a + a * math.sin(alpha), x_a - a * math.cos(alpha))  # Eq 18
    lever = np.cos(lam) * math.sin(alpha) + np.sin(lam) * math.cos(alpha)  # = sin(λ + α)
    torque: FloatArray = -geometry.n_springs * force * a * lever  # Eq 13
    return torque
