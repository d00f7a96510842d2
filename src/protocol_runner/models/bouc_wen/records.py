"""The records of a Bouc-Wen fit (thesis §6.2.3, Figure 56): the bounds of the fitted parameters, relative
to the data, and the fit's result."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from protocol_runner.errors import InvalidInput

from .backbone import Backbone, FixedBackbone
from .params import BoucWenParams, FloatArray
from .schemes import REFINED


@dataclass(frozen=True)
class BoucWenBounds:
    """Bounds of the fitted parameters, expressed relative to the data so that they suit any joint.

    With ``X`` the largest |angle| (deg) and ``Z`` the largest |torque| (N*m) of the fitted data, Eq 20
    becomes ``dz'/dx' = a - |z'|^n psi'`` for ``z' = z/Z`` and ``x' = x/X``, with ``a = A X / Z`` and
    ``psi' = psi X Z^(n-1)``.  The bounds are on these dimensionless numbers:

    * ``0 <= a <= a_max`` - ``A >= 0`` makes the torque rise with the angle near ``z = 0`` (a passive joint
      resists the motion); ``a_max = 20`` lets the initial slope be 20 times the loop's mean secant slope
      ``Z/X`` (for X = 65 deg, Z = 20 N*m: A <= 6.2 N*m/deg).
    * ``n_min <= n <= n_max`` (0.5-3): the exponent only shapes the knees of the loop; the thesis fitted
      1.2.
    * ``|psi'_k| <= psi_max`` for the six Table 4 phase values (hence ``|beta'_k| <= psi_max`` too, since
      each row of Eq 25 has four entries of 1/4).  ``psi_max = 100`` allows slopes up to about
      ``dz'/dx' = 100``, i.e. crossing the whole torque range within 1 % of the angle range; the Figure 57
      parameters on a +-65 deg, 20 N*m loop have ``psi'_5 = -57``.  In physical units (X = 65 deg,
      Z = 20 N*m, n = 1.2) this is about ``|psi_k| <= 0.83`` N*m^(1-n)/deg, against 0.47 for Figure 57.

    The fitter also treats |z| > 10 Z as divergence (see :func:`fit`).
    """

    a_max: float = 20.0
    n_min: float = 0.5
    n_max: float = 3.0
    psi_max: float = 100.0

    def __post_init__(self) -> None:
        if not (0.0 < self.a_max < math.inf):
            raise InvalidInput(f"BoucWenBounds.a_max must be positive and finite, got {self.a_max}")
        if not (0.0 < self.n_min < self.n_max < math.inf):
            raise InvalidInput(f"BoucWenBounds needs 0 < n_min < n_max, got {self.n_min}, {self.n_max}")
        if not (0.0 < self.psi_max < math.inf):
            raise InvalidInput(f"BoucWenBounds.psi_max must be positive and finite, got {self.psi_max}")

    def lower(self) -> FloatArray:
        return np.array([0.0, self.n_min, *([-self.psi_max] * 6)])

    def upper(self) -> FloatArray:
        return np.array([self.a_max, self.n_max, *([self.psi_max] * 6)])


DEFAULT_BOUNDS = BoucWenBounds()
FULL_REFIT_R2 = 0.5  # below this on every sample, a decimated fit is redone on every sample (fit_trials)


@dataclass(frozen=True)
class BoucWenFit:
    """Result of :func:`fit` / :func:`fit_trials`.

    params: best-fitting parameters (physical units, see :class:`BoucWenParams`).
    rmse_nm: root-mean-square torque error over every given sample of every trial, with each trial's
        recursion started at its own first torque.
    r2: coefficient of determination over the same samples, of the torque the Bouc-Wen state models (with
        a backbone ``torque = g(angle) + z``, the torque left after ``g``).
    param_std: 1-sigma uncertainties of (A, n, beta1..6) from the Jacobian at the optimum,
        ``sqrt(diag(s^2 (J^T J)^-1))`` on the fitted samples; ``inf`` for a direction the data cannot
        determine (e.g. a Table 4 phase never visited).  Optimistic for correlated residuals:
        :func:`.identifiability.identify` (which the pipeline runs) replaces them with its Wald sigmas.
    n_starts: number of starting points tried; converged: the final local solve met its tolerance;
    diverged: the fitted model's recursion left the data's torque range by a factor 10 on the given samples.
    trial_rmse_nm: RMSE of each trial; n_samples: samples given; n_samples_fitted: samples the optimiser
        used after decimation; stride: decimation step of each trial; nfev: residual evaluations in total.
    angle_scale_deg, torque_scale_nm: the scales X and Z that make :class:`BoucWenBounds` physical.
    message: the final least-squares solver's termination message; status: its status code
        (``scipy.optimize.least_squares``: 1-4 converged by gtol/ftol/xtol/both, 0 evaluation limit).
    scheme: the integration the fit used (``"refined"`` or ``"eq23"``, see :func:`simulate`).
    rmse_refined_nm: the same parameters re-simulated with 4x finer integration, compared at the given
        samples; agrees with ``rmse_nm`` for a fit that describes the joint rather than the integrator.
    start_rmse_nm: each start's RMSE (N*m, on the screening copy after its short solve), best first;
        polished_rmse_nm: the RMSE on the fitted samples of each start refined to convergence.
    n_interval, param_interval_low/high, weakly_identified, weak_reasons: see
        :func:`.identifiability.identify` (empty/NaN unless asked for).
    """

    params: BoucWenParams
    rmse_nm: float
    r2: float
    param_std: FloatArray
    n_starts: int
    converged: bool
    diverged: bool
    trial_rmse_nm: tuple[float, ...]
    n_samples: int
    n_samples_fitted: int
    stride: tuple[int, ...]
    nfev: int
    angle_scale_deg: float
    torque_scale_nm: float
    bounds: BoucWenBounds = field(default=DEFAULT_BOUNDS)
    message: str = ""
    scheme: str = REFINED
    rmse_refined_nm: float = math.nan
    status: int = 0
    start_rmse_nm: tuple[float, ...] = ()
    polished_rmse_nm: tuple[float, ...] = ()
    # filled by fit_trials when asked (identifiability.py)
    n_interval: tuple[float, float] = (math.nan, math.nan)
    param_interval_low: tuple[float, ...] = ()
    param_interval_high: tuple[float, ...] = ()
    weakly_identified: bool = False
    weak_reasons: tuple[str, ...] = ()
    # torque = backbone(angle) + z when set (fit_trials backbone_degree or backbone_factory)
    backbone: Backbone | FixedBackbone | None = None

    @property
    def cost_spread(self) -> float:
        """Relative spread of the best (up to three) starts' RMSEs after their short solves:
        ``(rmse_3 - rmse_1) / rmse_1``; 0 when they found the same valley, NaN with one start."""
        best = self.start_rmse_nm[:3]
        if len(best) < 2 or not best[0] > 0.0:
            return math.nan
        return (best[-1] - best[0]) / best[0]
