"""Statistical power of the report's tests, and the trials per configuration a statement needs
(docs/protocol.md "Trials needed").

The report decides an expectation on trial values with one-sided Welch tests of a contrast, or with two
one-sided tests (TOST) of equivalence. A contrast C = sum(w_i mu_i) estimated from `n` trials per
configuration has se = sqrt(sum(w_i^2 sigma_i^2) / n) and Welch-Satterthwaite df = (n - 1) (sum v_i)^2 /
sum v_i^2, v_i = w_i^2 sigma_i^2; its t statistic is noncentral t with noncentrality effect / se (Cohen 1988,
ch. 2; Welch 1947, Satterthwaite 1946), so:

- one-sided test at level alpha of an effect delta > 0: power = P(T' > t_(1-alpha, df)), T' ~ nct(df, delta / se);
- TOST of a true value theta inside (low, high) (Schuirmann 1987): power >= P(T1 > t) + P(T2 > t) - 1, with
  T1 ~ nct(df, (theta - low) / se), T2 ~ nct(df, (high - theta) / se) (Bonferroni's inequality: a lower
  bound, close when the power is high);
- a statement of several parts holds only when every part does (intersection-union): power >= 1 - sum(1 -
  power_i).

The report's Welch test estimates df from the trials, lower than the planning SDs' value, so with few
trials and a small alpha its real power is below the computed one (0.76 instead of 0.80 at 6 trials, two
configurations of equal SD, alpha 0.0028): a computed count is the least that could decide a statement.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy import stats

#: Power a plan asks for: the probability that a true statement is decided (met).
POWER_TARGET = 0.8

#: The largest trial count searched (a statement that needs more is reported as needing more than this).
MOST_TRIALS = 1000


@dataclass(frozen=True)
class OneSided:
    """A one-sided test of a contrast: `effect` is the true contrast minus its reference, signed so that
    positive supports the statement; `sd_terms` are |w_i| * sigma_i, one per configuration of the contrast."""

    effect: float
    sd_terms: tuple[float, ...]


@dataclass(frozen=True)
class Equivalence:
    """Two one-sided tests (TOST) that a contrast lies inside (`low`, `high`), its true value `true_value`;
    `sd_terms` as for `OneSided`."""

    true_value: float
    low: float
    high: float
    sd_terms: tuple[float, ...]


Part = OneSided | Equivalence


def standard_error(sd_terms: Sequence[float], n: int) -> float:
    """Standard error of a contrast estimated from `n` trials per configuration: sqrt(sum(s_i^2) / n)."""
    return math.sqrt(sum(s * s for s in sd_terms) / n)


def welch_dof(sd_terms: Sequence[float], n: int) -> float:
    """Welch-Satterthwaite degrees of freedom of a contrast with `n` trials per configuration:
    (n - 1) (sum v_i)^2 / sum v_i^2, v_i = s_i^2 (n - 1 for one configuration or one non-zero term)."""
    v = [s * s for s in sd_terms]
    total, squares = sum(v), sum(x * x for x in v)
    return (n - 1) * total * total / squares if squares > 0.0 else float(n - 1)


def _upper(critical: float, dof: float, noncentrality: float) -> float:
    """P(T' > critical) for T' ~ nct(dof, noncentrality); a noncentrality of +-inf gives 1 or 0."""
    if math.isinf(noncentrality):
        return 1.0 if noncentrality > 0 else 0.0
    return float(stats.nct.sf(critical, dof, noncentrality))


def _ratio(numerator: float, se: float) -> float:
    if se > 0.0:
        return numerator / se
    return math.inf if numerator > 0.0 else -math.inf  # no spread: the sign of the effect decides


def part_power(part: Part, n: int, alpha: float) -> float:
    """Power (a lower bound for TOST) of one test at level `alpha` (one-sided, each side for TOST) with `n`
    trials per configuration, n >= 2."""
    if n < 2:
        raise ValueError(f"n = {n}: a t-test needs two trials per configuration")
    se = standard_error(part.sd_terms, n)
    dof = welch_dof(part.sd_terms, n)
    critical = float(stats.t.ppf(1.0 - alpha, dof))
    if isinstance(part, OneSided):
        return _upper(critical, dof, _ratio(part.effect, se))
    if not part.low < part.true_value < part.high:
        return 0.0  # a true value on or outside a bound: the test's size, at most alpha; no power to plan on
    lower = _upper(critical, dof, _ratio(part.true_value - part.low, se))
    upper = _upper(critical, dof, _ratio(part.high - part.true_value, se))
    return max(0.0, lower + upper - 1.0)


def statement_power(parts: Sequence[Part], n: int, alpha: float) -> float:
    """Lower bound of the power of a statement that holds only when every part does:
    1 - sum(1 - power_i) (at least 0); one part: its own power."""
    if len(parts) == 1:
        return part_power(parts[0], n, alpha)
    return max(0.0, 1.0 - sum(1.0 - part_power(p, n, alpha) for p in parts))


def trials_needed(
    parts: Sequence[Part],
    alpha: float,
    target: float = POWER_TARGET,
    least: int = 2,
    most: int = MOST_TRIALS,
) -> int | None:
    """The smallest number of trials per configuration, from `least` (at least 2) to `most`, whose
    statement power (`statement_power`) at level `alpha` reaches `target`; None when even `most` do not.

    The power grows with n (the noncentralities grow as sqrt(n), the critical values fall as the degrees of
    freedom grow), so the count is bracketed by doubling and then found by bisection."""
    if not parts:
        raise ValueError("a statement needs at least one part")

    def enough(n: int) -> bool:
        return statement_power(parts, n, alpha) >= target

    low = max(2, least)
    if enough(low):
        return low
    high = low
    while True:  # enough(high) is False here: double until enough, or `most`
        if high >= most:
            return None
        low, high = high, min(2 * high, most)
        if enough(high):
            break
    while high - low > 1:  # not enough at low, enough at high
        mid = (low + high) // 2
        low, high = (low, mid) if enough(mid) else (mid, high)
    return high
