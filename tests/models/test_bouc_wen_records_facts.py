"""Facts of the Bouc-Wen fit's records (records.py): the bounds are a box around admissible dimensionless
parameters (thesis §6.2.3), documented where they are defined, and a fit's cost spread compares its best
three starts."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS, BoucWenBounds, BoucWenFit

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


@pytest.mark.parametrize(
    "kwargs",
    [
        {"a_max": 0.0},
        {"a_max": -1.0},
        {"a_max": math.inf},
        {"n_min": 0.0},
        {"n_min": -0.5},
        {"n_min": 3.0, "n_max": 3.0},
        {"n_min": 2.0, "n_max": 1.0},
        {"n_max": math.inf},
        {"psi_max": 0.0},
        {"psi_max": -1.0},
        {"psi_max": math.inf},
        # the same limits computed rather than written: no identity with the module's own constants
        {"a_max": float("inf")},
        {"n_max": float("inf")},
        {"psi_max": float("inf")},
        {"n_min": float("0")},
        {"n_min": float("3"), "n_max": float("3")},
    ],
)
def test_bounds_that_leave_no_finite_positive_box_are_invalid_input(kwargs: dict) -> None:
    with pytest.raises(InvalidInput, match="BoucWenBounds"):
        BoucWenBounds(**kwargs)


def test_the_smallest_admissible_bounds_are_accepted() -> None:
    tiny = BoucWenBounds(a_max=1e-9, n_min=1e-9, n_max=2e-9, psi_max=1e-9)
    assert tiny.lower()[1] < tiny.upper()[1]


def test_the_box_holds_a_passive_joint_and_symmetric_shape_values() -> None:
    """A >= 0 (a passive joint resists motion), n_min <= n <= n_max, |psi'_k| <= psi_max for the six
    Table 4 phase values: the order is (a, n, psi'_1..6)."""
    b = BoucWenBounds(a_max=7.0, n_min=0.7, n_max=2.5, psi_max=40.0)
    lower, upper = b.lower(), b.upper()
    assert lower.shape == upper.shape == (8,)
    assert lower[0] == 0.0 and upper[0] == 7.0
    assert lower[1] == 0.7 and upper[1] == 2.5
    np.testing.assert_array_equal(lower[2:], np.full(6, -40.0))
    np.testing.assert_array_equal(upper[2:], np.full(6, 40.0))


def test_the_default_bounds_are_the_documented_ones_and_hold_figure_57() -> None:
    """The docstring states a_max = 20, n in 0.5-3 and psi_max = 100; the Figure 57 parameters on a
    +-65 deg, 20 N*m loop (psi'_5 = -57 there) lie inside."""
    doc = BoucWenBounds.__doc__ or ""
    a_max = float(re.search(r"a_max = (\d+(?:\.\d+)?)", doc).group(1))  # type: ignore[union-attr]
    n_lo, n_hi = (float(v) for v in re.search(r"\((\d+(?:\.\d+)?)-(\d+(?:\.\d+)?)\)", doc).groups())  # type: ignore[union-attr]
    psi_max = float(re.search(r"psi_max = (\d+(?:\.\d+)?)", doc).group(1))  # type: ignore[union-attr]
    assert (DEFAULT_BOUNDS.a_max, DEFAULT_BOUNDS.n_min, DEFAULT_BOUNDS.n_max, DEFAULT_BOUNDS.psi_max) == (
        a_max,
        n_lo,
        n_hi,
        psi_max,
    )
    assert BoucWenBounds() == DEFAULT_BOUNDS
    x_deg, z_nm = 65.0, 20.0
    a = FIG57.A * x_deg / z_nm
    assert DEFAULT_BOUNDS.lower()[0] <= a <= DEFAULT_BOUNDS.upper()[0]
    assert DEFAULT_BOUNDS.lower()[1] <= FIG57.n <= DEFAULT_BOUNDS.upper()[1]
    assert DEFAULT_BOUNDS.lower()[2] < -57.0


def _fit(start_rmse: tuple[float, ...]) -> BoucWenFit:
    base = BoucWenFit(
        params=FIG57,
        rmse_nm=1.0,
        r2=0.9,
        param_std=np.zeros(8),
        n_starts=len(start_rmse),
        converged=True,
        diverged=False,
        trial_rmse_nm=(1.0,),
        n_samples=10,
        n_samples_fitted=10,
        stride=(1,),
        nfev=1,
        angle_scale_deg=65.0,
        torque_scale_nm=20.0,
    )
    return replace(base, start_rmse_nm=start_rmse)


def test_starts_that_found_the_same_valley_have_no_spread() -> None:
    assert _fit((2.0, 2.0, 2.0, 9.0)).cost_spread == 0.0


def test_the_spread_is_the_third_best_relative_to_the_best() -> None:
    """(rmse_3 - rmse_1) / rmse_1 over the best three only: a fourth, worse start does not count."""
    assert _fit((2.0, 2.5, 3.0, 40.0)).cost_spread == pytest.approx(0.5)
    assert _fit((2.0, 3.0)).cost_spread == pytest.approx(0.5)


def test_the_spread_is_a_ratio_whatever_the_size_of_the_errors() -> None:
    """A relative spread does not depend on the unit: starts whose errors are all below 1 N*m have it too."""
    assert _fit((0.2, 0.25, 0.3)).cost_spread == pytest.approx(0.5)
    assert _fit((0.002, 0.003)).cost_spread == pytest.approx(0.5)


def test_a_fit_not_examined_for_identifiability_carries_no_weak_mark() -> None:
    """The intervals and the weak-identification mark are filled only when identify() is asked for; until
    then the record claims nothing: no mark, no reasons, no intervals."""
    plain = _fit((2.0, 3.0))
    assert plain.weakly_identified is False
    assert plain.weak_reasons == ()
    assert plain.param_interval_low == plain.param_interval_high == ()
    assert all(math.isnan(v) for v in plain.n_interval)


@pytest.mark.parametrize("rmse", [(), (2.0,), (0.0, 1.0, 2.0)])
def test_the_spread_is_undefined_with_one_start_or_a_perfect_best(rmse: tuple[float, ...]) -> None:
    assert math.isnan(_fit(rmse).cost_spread)
