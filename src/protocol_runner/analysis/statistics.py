"""Trial-level statistics: the trial is the experimental unit, not the cycle (cycles within one trial share
mounting, warm-up and brake state).

A configuration's energy per cycle is the mean of its trial means with a Student t-interval over trials;
two configurations differ with a Welch interval; repeatability of identical configurations run in
different sets is their between-configuration CV and the ICC(1) of the trial means.

Decisions (report/evaluate.py) are taken at the family-wise level `ALPHA`: one-sided tests for a stated
direction, two one-sided tests (TOST) for an equivalence within a margin, Holm across a family.

Student t quantiles and tails are `scipy.special.stdtrit` and `stdtr`, the functions `scipy.stats.t`
computes them with (the same numbers), without importing all of `scipy.stats` into every report.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy import special

#: Confidence level of every interval in reports and exports.
CONFIDENCE = 0.95

#: Family-wise significance level of the report's decisions (expectations, differences).
ALPHA = 0.05


class _Bounds:
    """What any interval (`low`, `high`) tells: its half width and whether it excludes zero."""

    low: float
    high: float

    @property
    def half_width(self) -> float:
        """Half the interval's width (NaN when undefined)."""
        return (self.high - self.low) / 2.0

    @property
    def significant(self) -> bool:
        """True when the interval excludes zero (NaN bounds: False)."""
        return bool(self.low > 0.0 or self.high < 0.0)


class _Estimate(_Bounds):
    """A t-based estimate (`difference`) with its interval and degrees of freedom."""

    difference: float
    dof: float
    confidence: float

    @property
    def standard_error(self) -> float:
        """The estimate's standard error, from the interval's half width (0 for constant groups)."""
        if self.half_width == 0.0:
            return 0.0
        return self.half_width / float(special.stdtrit(self.dof, 0.5 + self.confidence / 2.0))


@dataclass(frozen=True)
class TInterval(_Bounds):
    """Mean of `n` units with its two-sided t-interval; `low`/`high` are NaN when n < 2."""

    n: int
    mean: float
    sd: float
    low: float
    high: float
    confidence: float = CONFIDENCE

    @property
    def cv(self) -> float:
        """Between-unit coefficient of variation sd / |mean| (NaN when undefined)."""
        if self.n < 2 or not math.isfinite(self.mean) or self.mean == 0.0:
            return math.nan
        return self.sd / abs(self.mean)


@dataclass(frozen=True)
class WelchInterval(_Estimate):
    """Difference `b - a` of two means with its Welch t-interval and p-value."""

    difference: float
    low: float
    high: float
    dof: float
    p_value: float
    confidence: float = CONFIDENCE


@dataclass(frozen=True)
class Repeatability:
    """Agreement of identical configurations run in different sets (units: their trial means)."""

    groups: int
    units: int
    grand_mean: float
    between_cv: float
    icc: float  # the ANOVA estimate as computed: negative when the sets agree less than chance would

    @property
    def icc_shown(self) -> float:
        """The ICC as reported: a negative estimate is shown as 0 (a correlation of a variance share
        cannot be below 0; the estimate is negative when the within-set spread exceeds the between-set)."""
        return max(0.0, self.icc) if math.isfinite(self.icc) else math.nan

    @property
    def icc_note(self) -> str:
        """Why the shown ICC differs from the estimate ("" when it does not)."""
        if math.isfinite(self.icc) and self.icc < 0.0:
            return (
                f"negative estimate ({self.icc:.2f}) shown as 0: the sets' means differ no more than "
                "their trials do (no between-set variance beyond chance)"
            )
        return ""


def _finite(values: npt.ArrayLike) -> np.ndarray:
    arr = np.asarray(values, dtype=float).ravel()
    return arr[np.isfinite(arr)]


def trial_means(values: npt.ArrayLike, trial_ids: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Per-trial means of `values` grouped by `trial_ids` (same length), in trial order; NaNs ignored."""
    vals = np.asarray(values, dtype=float).ravel()
    ids = np.asarray(trial_ids).ravel()
    if vals.size != ids.size:
        raise ValueError(f"{vals.size} values but {ids.size} trial ids")
    numbers: list[int] = []
    means: list[float] = []
    for number in np.unique(ids):
        own = vals[(ids == number) & np.isfinite(vals)]
        if own.size:
            numbers.append(int(number))
            means.append(float(own.mean()))
    return np.asarray(numbers, dtype=np.int64), np.asarray(means, dtype=float)


def t_interval(values: npt.ArrayLike, confidence: float = CONFIDENCE) -> TInterval:
    """Mean of `values` (one per unit) with its two-sided Student t-interval."""
    arr = _finite(values)
    n = int(arr.size)
    if n == 0:
        return TInterval(0, math.nan, math.nan, math.nan, math.nan, confidence)
    mean = float(arr.mean())
    if n < 2:
        return TInterval(1, mean, math.nan, math.nan, math.nan, confidence)
    sd = float(arr.std(ddof=1))
    half = float(special.stdtrit(n - 1, 0.5 + confidence / 2.0)) * sd / math.sqrt(n)
    return TInterval(n, mean, sd, mean - half, mean + half, confidence)


def coefficient_of_variation(values: npt.ArrayLike) -> float:
    """Sample CV (ddof=1) of `values`; NaN for fewer than two values or a zero mean."""
    return t_interval(values).cv


def welch_interval(a: npt.ArrayLike, b: npt.ArrayLike, confidence: float = CONFIDENCE) -> WelchInterval:
    """Difference of means `mean(b) - mean(a)` with a Welch interval; NaN bounds if either has < 2 units.

    Two groups that are both constant give a zero-width interval around their difference (p 0 or 1).
    """
    x, y = _finite(a), _finite(b)
    if x.size < 2 or y.size < 2:
        diff = float(y.mean() - x.mean()) if x.size and y.size else math.nan
        return WelchInterval(diff, math.nan, math.nan, math.nan, math.nan, confidence)
    diff = float(y.mean() - x.mean())
    vx, vy = float(x.var(ddof=1)) / x.size, float(y.var(ddof=1)) / y.size
    se2 = vx + vy
    if se2 == 0.0:
        return WelchInterval(diff, diff, diff, math.inf, 1.0 if diff == 0.0 else 0.0, confidence)
    dof = se2**2 / (vx**2 / (x.size - 1) + vy**2 / (y.size - 1))
    se = math.sqrt(se2)
    half = float(special.stdtrit(dof, 0.5 + confidence / 2.0)) * se
    p_value = float(2.0 * special.stdtr(dof, -(abs(diff) / se)))
    return WelchInterval(diff, diff - half, diff + half, dof, p_value, confidence)


def contrast_interval(
    terms: Sequence[tuple[float, npt.ArrayLike]], confidence: float = CONFIDENCE
) -> WelchInterval:
    """A linear contrast C = sum(w_i * mean_i) of independent groups with its Welch-Satterthwaite interval.

    Var(C) = sum(w_i^2 s_i^2 / n_i); degrees of freedom Var(C)^2 / sum((w_i^2 s_i^2 / n_i)^2 / (n_i - 1)).
    One group with weight 1 is its mean's Student t-interval (n - 1 degrees of freedom); the groups
    `[(-1, a), (1, b)]` give `welch_interval(a, b)`; four groups `[(1, a), (-1, b), (-1, c), (1, d)]`
    give the difference of differences (a - b) - (c - d). NaN bounds when any group has fewer than two
    units; the p-value tests C = 0.
    """
    groups = [(float(w), _finite(x)) for w, x in terms]
    if not groups or any(x.size == 0 for _, x in groups):
        return WelchInterval(math.nan, math.nan, math.nan, math.nan, math.nan, confidence)
    value = float(sum(w * x.mean() for w, x in groups))
    if any(x.size < 2 for _, x in groups):
        return WelchInterval(value, math.nan, math.nan, math.nan, math.nan, confidence)
    parts = [w * w * float(x.var(ddof=1)) / x.size for w, x in groups]
    variance = sum(parts)
    if variance == 0.0:
        return WelchInterval(value, value, value, math.inf, 1.0 if value == 0.0 else 0.0, confidence)
    dof = variance**2 / sum(v * v / (x.size - 1) for v, (_, x) in zip(parts, groups, strict=True))
    se = math.sqrt(variance)
    half = float(special.stdtrit(dof, 0.5 + confidence / 2.0)) * se
    p_value = float(2.0 * special.stdtr(dof, -(abs(value) / se)))
    return WelchInterval(value, value - half, value + half, dof, p_value, confidence)


def _one_sided(estimate: _Estimate, shift: float) -> float:
    """P(T >= shift / se) under the null: the p-value of "the true value exceeds the estimate minus shift"."""
    se = estimate.standard_error
    if not (math.isfinite(shift) and math.isfinite(se)):
        return math.nan
    if se == 0.0:
        return 0.0 if shift > 0.0 else 1.0
    return float(special.stdtr(estimate.dof, -(shift / se)))


def p_above(estimate: _Estimate, ref: float = 0.0) -> float:
    """One-sided p-value of "the true value is above `ref`" (H0: at most `ref`); NaN when undefined."""
    return _one_sided(estimate, estimate.difference - ref)


def p_below(estimate: _Estimate, ref: float = 0.0) -> float:
    """One-sided p-value of "the true value is below `ref`" (H0: at least `ref`); NaN when undefined."""
    return _one_sided(estimate, ref - estimate.difference)


def holm(p_values: Sequence[float]) -> list[float]:
    """Holm's step-down adjusted p-values of one family, in the given order (capped at 1, monotone in the
    sorted order). A NaN p-value is not a member of the family and stays NaN.

    Sorted ascending, the i-th of m p-values (i from 0) is multiplied by m - i; each adjusted value is the
    running maximum of these, so rejecting when the adjusted p is at most alpha is Holm's procedure: the
    family-wise error rate is at most alpha under any dependence between the tests.
    """
    members = sorted((p, i) for i, p in enumerate(p_values) if math.isfinite(p))
    m = len(members)
    out = [math.nan] * len(p_values)
    running = 0.0
    for rank, (p, i) in enumerate(members):
        running = max(running, min(1.0, (m - rank) * p))
        out[i] = running
    return out


def repeatability(groups: Sequence[npt.ArrayLike]) -> Repeatability:
    """Between-group CV and one-way random-effects ICC(1) of unit values (e.g. trial means) per group.

    ICC(1) = (MSB - MSW) / (MSB + (n0 - 1) MSW), with n0 the ANOVA's effective group size for unequal
    groups; NaN when fewer than two groups or no within-group replication. The between-group CV is the
    sample standard deviation of the group means over the grand mean.
    """
    arrays = [g for g in (_finite(x) for x in groups) if g.size]
    k = len(arrays)
    units = sum(int(g.size) for g in arrays)
    if k == 0:
        return Repeatability(0, 0, math.nan, math.nan, math.nan)
    grand = float(np.concatenate(arrays).mean())
    means = np.asarray([g.mean() for g in arrays])
    between_cv = coefficient_of_variation(means) if k >= 2 else math.nan
    if k < 2 or units <= k:
        return Repeatability(k, units, grand, between_cv, math.nan)
    sizes = np.asarray([g.size for g in arrays], dtype=float)
    ss_between = float(np.sum(sizes * (means - grand) ** 2))
    ss_within = float(sum(np.sum((g - g.mean()) ** 2) for g in arrays))
    msb = ss_between / (k - 1)
    msw = ss_within / (units - k)
    n0 = (units - float(np.sum(sizes**2)) / units) / (k - 1)
    denominator = msb + (n0 - 1.0) * msw
    icc = (msb - msw) / denominator if denominator > 0.0 else math.nan
    return Repeatability(k, units, grand, between_cv, float(icc))
