"""Energy per cycle on coarse loops: the closed trapezoid sum is the exact area of the sampled polygon."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.energy import (
    cycle_energy_j,
    energy_per_cycle,
    loop_integral_deg_nm,
    summarize_energy,
)
from protocol_runner.analysis.validation import AnalysisError

DEG = np.pi / 180.0


def _polygon(n: int, a: float, b: float, phi: float, offset_nm: float, shift_deg: float = 0.0):
    """n samples of one cycle: angle = shift + a sin(2 pi k / n), torque = offset + b sin(2 pi k / n + phi)."""
    wt = 2 * np.pi * np.arange(n) / n
    return shift_deg + a * np.sin(wt), offset_nm + b * np.sin(wt + phi)


@pytest.mark.parametrize("n", [5, 8, 12])
def test_coarse_offset_loop_energy_is_the_area_of_its_polygon(n: int) -> None:
    # shoelace area of the n-gon inscribed in the ellipse: (n / 2) a b sin(2 pi / n) sin(phi), whatever the
    # torque offset (an unclosed trapezoid sum would carry a term proportional to the offset)
    a, b, phi = 40.0, 6.0, 0.6
    angle, torque = _polygon(n, a, b, phi, offset_nm=25.0, shift_deg=50.0)
    area = 0.5 * n * a * b * np.sin(2 * np.pi / n) * np.sin(phi)
    assert loop_integral_deg_nm(angle, torque) == pytest.approx(area, rel=1e-12)
    assert cycle_energy_j(angle, torque) == pytest.approx(area * DEG, rel=1e-12)


def test_a_square_loop_traversed_clockwise_dissipates_its_area() -> None:
    # loading at 5 N m from 10 to 30 deg, unloading at 2 N m: area 20 deg x 3 N m
    angle = np.array([10.0, 30.0, 30.0, 10.0])
    torque = np.array([5.0, 5.0, 2.0, 2.0])
    assert loop_integral_deg_nm(angle, torque) == pytest.approx(60.0)
    assert cycle_energy_j(angle, torque) == pytest.approx(60.0 * np.pi / 180.0)
    # starting the same loop at another corner changes nothing
    assert loop_integral_deg_nm(np.roll(angle, 1), np.roll(torque, 1)) == pytest.approx(60.0)


def test_each_complete_cycle_of_a_coarse_trial_has_the_polygon_area() -> None:
    n, a, b, phi = 16, 30.0, 5.0, 0.5
    wt = 2 * np.pi * (np.arange(5 * n + 3) + 0.5) / n  # five and a bit cycles, starting just past a crossing
    angle, torque = 60.0 + a * np.sin(wt), 40.0 + b * np.sin(wt + phi)
    e = energy_per_cycle(angle, torque)
    area = 0.5 * n * a * b * np.sin(2 * np.pi / n) * np.sin(phi)
    assert e.size == 4
    np.testing.assert_allclose(e, area * DEG, rtol=1e-9)


def test_two_samples_enclose_no_area_and_one_is_not_a_loop() -> None:
    assert loop_integral_deg_nm([10.0, 20.0], [1.0, 5.0]) == 0.0  # out and back along the same segment
    with pytest.raises(AnalysisError, match="at least 2 samples"):
        loop_integral_deg_nm([10.0], [1.0])


def test_summary_of_two_cycles_is_the_sample_standard_deviation() -> None:
    s = summarize_energy([np.array([1.0]), np.array([3.0])])
    assert (s.mean_j, s.n) == (2.0, 2)
    assert s.std_j == pytest.approx(np.sqrt(2.0))  # |a - b| / sqrt(2) with ddof = 1
    empty = summarize_energy([])
    assert empty.n == 0 and np.isnan(empty.mean_j) and np.isnan(empty.std_j)
