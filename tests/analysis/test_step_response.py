"""The calibration check's first-order model (thesis §2.4.2) and its time constant
(`steps/calibration_check.py`): the model answers a step exactly as ``tau dy/dt = c - y`` does, and the
least-squares time constant of a noisy first-order response is the true one."""

from __future__ import annotations

import numpy as np

from protocol_runner.steps.calibration_check import TAU_BOUNDS_S, analyse_step, first_order_response


def test_the_response_to_a_step_is_the_exponential_approach_of_a_first_order_lag() -> None:
    dt, tau, y0, target = 0.001, 0.2, 20.0, 65.0
    command = np.full(3000, target)
    t = np.arange(command.size) * dt
    expected = target + (y0 - target) * np.exp(-t / tau)
    response = first_order_response(command, dt, tau, y0)
    assert response[0] == y0
    np.testing.assert_allclose(response, expected, rtol=0.0, atol=1e-10)


def test_the_time_constant_of_a_noisy_first_order_response_is_found() -> None:
    rng = np.random.default_rng(5)
    for _ in range(12):
        tau_true = float(rng.uniform(0.05, 1.2))
        t = np.arange(6000) / 1000.0
        command = np.where(t >= 0.5, 65.0, 20.0)
        angle = first_order_response(command, 0.001, tau_true, 20.0) + rng.normal(0.0, 0.05, t.size)
        found = analyse_step(t, command, angle, 65.0, 1.0)
        assert abs(found.time_constant_s - tau_true) < 0.01
        assert TAU_BOUNDS_S[0] <= found.time_constant_s <= TAU_BOUNDS_S[1]
