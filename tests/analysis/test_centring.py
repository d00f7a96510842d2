"""Centring of a loop on (0, 0) by the trial mean (thesis §6.2.3 note)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.centring import centre
from protocol_runner.analysis.energy import energy_per_cycle


def test_centred_loop_has_zero_mean_and_keeps_the_means() -> None:
    t = np.linspace(0.0, 10.0, 5001)
    angle = 65.0 + 40.0 * np.sin(2 * np.pi * t / 2.5)
    torque = 12.0 + 8.0 * np.sin(2 * np.pi * t / 2.5 + 0.4)
    loop = centre(angle, torque)
    assert loop.angle_deg.mean() == pytest.approx(0.0, abs=1e-12)
    assert loop.torque_nm.mean() == pytest.approx(0.0, abs=1e-12)
    assert loop.mean_angle_deg == pytest.approx(angle.mean())
    assert loop.mean_torque_nm == pytest.approx(torque.mean())
    np.testing.assert_allclose(loop.angle_deg + loop.mean_angle_deg, angle)
    # centring moves the loop, it does not change its area
    np.testing.assert_allclose(
        energy_per_cycle(loop.angle_deg, loop.torque_nm), energy_per_cycle(angle, torque)
    )
