"""The Eq 23 kernels on cases with a closed form: with every beta zero the recursion is the straight line
z = z0 + A (x - x0), so where it crosses a divergence bound is known to the sample."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.models.bouc_wen import BoucWenParams, simulate, simulate_sensitivity
from protocol_runner.models.bouc_wen.kernels import recursion_kernel

LINE = BoucWenParams(A=1.0, n=1.0, beta=(0.0,) * 6)


def test_with_zero_betas_the_torque_is_a_line_of_slope_a() -> None:
    x = np.array([0.0, 1.0, 3.0, 2.0, -4.0, -4.0, 5.0])
    z = simulate(x, BoucWenParams(A=0.5, n=1.3, beta=(0.0,) * 6), z0=2.0)
    np.testing.assert_allclose(z, 2.0 + 0.5 * (x - x[0]), rtol=0, atol=1e-12)
    _, dz = simulate_sensitivity(x, BoucWenParams(A=0.5, n=1.3, beta=(0.0,) * 6), z0=2.0)
    np.testing.assert_allclose(dz[:, 0], x - x[0], atol=1e-12)  # d z / d A


def test_a_torque_reaching_the_bound_exactly_is_kept_and_the_next_one_diverges() -> None:
    x = np.arange(11.0)
    z = simulate(x, LINE, z0=0.0, bound_nm=5.0)
    np.testing.assert_array_equal(z[:6], [0.0, 1.0, 2.0, 3.0, 4.0, 5.0])
    assert np.all(np.isnan(z[6:]))


def test_the_fitter_holds_a_diverged_trial_at_the_bound_with_its_sign_and_restarts_the_next() -> None:
    # trial 1 falls through -5 at its 6th step, trial 2 rises gently from its own first torque
    x = np.concatenate([-np.arange(10.0), np.arange(6.0)])
    seg = np.array([0, 10, 16], dtype=np.int64)
    z0 = np.array([0.0, -2.0])
    z = np.empty_like(x)
    first_bad = recursion_kernel(x, seg, z0, 1.0, 1.0, np.zeros(6), 5.0, True, z)
    assert first_bad == 6
    np.testing.assert_array_equal(z[:6], [0.0, -1.0, -2.0, -3.0, -4.0, -5.0])
    np.testing.assert_array_equal(z[6:10], -5.0)
    np.testing.assert_array_equal(z[10:], [-2.0, -1.0, 0.0, 1.0, 2.0, 3.0])


def test_without_divergence_the_kernel_reports_none() -> None:
    x = np.arange(5.0)
    z = np.empty_like(x)
    assert recursion_kernel(x, np.array([0, 5]), np.array([0.0]), 1.0, 1.0, np.zeros(6), 4.0, True, z) == -1
    assert z[-1] == pytest.approx(4.0)
