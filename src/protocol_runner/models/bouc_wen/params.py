"""Bouc-Wen parameters and the Table 4 phase algebra (thesis §6.2.3, Eq 22, 24, 25)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from protocol_runner.errors import InvalidInput

FloatArray = npt.NDArray[np.float64]

PARAM_NAMES: tuple[str, ...] = ("A", "n", "beta1", "beta2", "beta3", "beta4", "beta5", "beta6")
"""Order of the eight model parameters in every vector, Jacobian column and ``param_std``."""

EQ24_PHASE_MATRIX: FloatArray = np.array(
    [
        [1, 1, 1, 1, 1, 1],
        [-1, -1, 1, -1, 1, 1],
        [1, -1, -1, -1, -1, 1],
        [1, 1, 1, -1, -1, -1],
        [-1, -1, 1, 1, -1, -1],
        [1, -1, -1, 1, 1, -1],
    ],
    dtype=np.float64,
)
"""Eq 24 (Table 4): ``psi = EQ24_PHASE_MATRIX @ beta``, rows are phases 1-6."""

EQ25_BETA_MATRIX: FloatArray = 0.25 * np.array(
    [
        [1, 0, 1, 1, 0, 1],
        [0, -1, -1, 0, -1, -1],
        [1, 1, 0, 1, 1, 0],
        [1, -1, 0, -1, 1, 0],
        [0, 1, -1, 0, -1, 1],
        [1, 0, 1, -1, 0, -1],
    ],
    dtype=np.float64,
)
"""Eq 25: ``beta = EQ25_BETA_MATRIX @ psi`` (1/4 times the matrix printed in the thesis)."""

# Table 4 phases as (sgn x, sgn dx, sgn z); the two remaining sign patterns (+,+,-) and (-,-,+) are not
# phases of Table 4 (Eq 23 still defines Psi there) and are reported as phase 0 by phase_of_samples().
_TABLE4_SIGNS: tuple[tuple[int, int, int], ...] = (
    (1, 1, 1),
    (1, -1, 1),
    (1, -1, -1),
    (-1, -1, -1),
    (-1, 1, -1),
    (-1, 1, 1),
)

DEFAULT_SIMULATION_BOUND_NM = 1.0e6
"""|z| beyond which :func:`simulate` declares the recursion diverged (the rest of the output is NaN)."""


@dataclass(frozen=True)
class BoucWenParams:
    """Parameters of the generalised Bouc-Wen model (Eq 22-23).

    A: scale of the hysteretic stiffness, N*m per degree (``dz/dx`` at ``z = 0``).
    n: exponent of ``|z|`` (dimensionless, > 0), controls the sharpness of the loop's knees.
    beta: the six shape coefficients of Eq 22, in N*m^(1-n) per degree.
    """

    A: float
    n: float
    beta: tuple[float, float, float, float, float, float]

    def __post_init__(self) -> None:
        try:
            A = float(self.A)
            n = float(self.n)
            beta = tuple(float(b) for b in self.beta)
        except (TypeError, ValueError):
            raise InvalidInput(
                f"BoucWenParams needs numbers: A, n and 6 betas, got A={self.A!r}, n={self.n!r}, "
                f"beta={self.beta!r}"
            ) from None
        if len(beta) != 6:
            raise InvalidInput(f"BoucWenParams.beta needs exactly 6 values (Eq 22), got {len(beta)}")
        if not all(math.isfinite(v) for v in (A, n, *beta)):
            raise InvalidInput(f"BoucWenParams must be finite numbers, got A={A}, n={n}, beta={beta}")
        if not n > 0.0:
            raise InvalidInput(f"BoucWenParams.n must be positive (|z|^n in Eq 23), got {n}")
        object.__setattr__(self, "A", A)
        object.__setattr__(self, "n", n)
        object.__setattr__(self, "beta", beta)

    def as_array(self) -> FloatArray:
        """The eight parameters as a vector in :data:`PARAM_NAMES` order."""
        return np.array([self.A, self.n, *self.beta], dtype=np.float64)

    @classmethod
    def from_array(cls, values: npt.ArrayLike) -> BoucWenParams:
        """Build from a vector ``(A, n, beta1..beta6)``."""
        v = np.asarray(values, dtype=np.float64).ravel()
        if v.size != 8:
            raise InvalidInput(f"a Bouc-Wen parameter vector has 8 entries (A, n, beta1..6), got {v.size}")
        b = v[2:]
        return cls(A=v[0], n=v[1], beta=(b[0], b[1], b[2], b[3], b[4], b[5]))

    @classmethod
    def from_phases(cls, A: float, n: float, psi: npt.ArrayLike) -> BoucWenParams:
        """Build from the six Table 4 phase values ``psi`` via Eq 25."""
        b = betas_from_phases(psi)
        return cls(A=A, n=n, beta=(b[0], b[1], b[2], b[3], b[4], b[5]))


def phase_values(beta: npt.ArrayLike) -> FloatArray:
    """Eq 24 / Table 4: the shape-function value ``psi_k`` in each of the six phases, from the betas."""
    b = np.asarray(beta, dtype=np.float64)
    if b.shape != (6,):
        raise InvalidInput(f"phase_values needs the 6 betas of Eq 22, got shape {b.shape}")
    return EQ24_PHASE_MATRIX @ b


def betas_from_phases(psi: npt.ArrayLike) -> FloatArray:
    """Eq 25: the six betas from the six Table 4 phase values ``psi_1..psi_6``."""
    p = np.asarray(psi, dtype=np.float64)
    if p.shape != (6,):
        raise InvalidInput(f"betas_from_phases needs the 6 phase values of Table 4, got shape {p.shape}")
    return EQ25_BETA_MATRIX @ p


def phase_of_samples(x_deg: npt.ArrayLike, z_nm: npt.ArrayLike) -> npt.NDArray[np.int64]:
    """Table 4 phase (1-6) of each step ``i -> i+1`` of a recursion (length ``len(x) - 1``).

    The phase is set by (sgn x_i, sgn(x_{i+1} - x_i), sgn z_i) as in Eq 23; steps whose sign pattern is
    not one of Table 4's six phases, or where a sign is zero, get phase 0.
    """
    x = np.asarray(x_deg, dtype=np.float64)
    z = np.asarray(z_nm, dtype=np.float64)
    if x.ndim != 1 or x.shape != z.shape:
        raise InvalidInput(
            f"phase_of_samples needs two 1-D arrays of one length, got {x.shape} and {z.shape}"
        )
    sx = np.sign(x[:-1])
    sd = np.sign(np.diff(x))
    sz = np.sign(z[:-1])
    phase = np.zeros(sx.shape, dtype=np.int64)
    for k, (px, pd, pz) in enumerate(_TABLE4_SIGNS, start=1):
        phase[(sx == px) & (sd == pd) & (sz == pz)] = k
    return phase
