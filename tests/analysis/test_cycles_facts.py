"""Upward crossings on short hand-made sequences whose crossings are known exactly."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.cycles import complete_cycles, reference_level, upward_crossings


def test_a_crossing_is_the_first_sample_at_or_above_the_reference() -> None:
    # reference 0 (the mean): up at sample 3 (from -2 to 0) and at sample 9 (from -1 to 3)
    d = np.array([0.0, -2.0, -2.0, 0.0, 2.0, 2.0, 0.0, -3.0, -1.0, 3.0, 1.0, 0.0])
    assert d.mean() == 0.0
    assert upward_crossings(d, hysteresis_deg=1.0).tolist() == [3, 9]
    assert complete_cycles(d, hysteresis_deg=1.0) == [(3, 9)]


def test_within_the_hysteresis_band_the_last_passage_counts() -> None:
    # below -h, then wiggles about the reference inside the band, then above +h: the crossing is where the
    # angle last rose through the reference (sample 6), not the first wiggle (sample 2)
    d = np.array([-5.0, -5.0, 0.5, -0.5, 0.5, -0.5, 0.5, 5.0, 5.0, -5.0, -5.0, 5.0])
    d = d - d.mean()
    ups = upward_crossings(d + 10.0, hysteresis_deg=2.0)
    assert ups.tolist() == [6, 11]


def test_without_hysteresis_touching_the_reference_from_below_counts() -> None:
    d = np.array([-1.0, 0.0, 1.0, -1.0, 0.0, 1.0])
    assert d.mean() == 0.0
    assert upward_crossings(d, hysteresis_deg=0.0).tolist() == [1, 4]


def test_default_hysteresis_is_a_tenth_of_the_robust_range() -> None:
    # a 100 deg peak-to-peak sine (h = 10 deg): wiggles of 8 deg about the mean are ignored, of 12 deg not
    k = np.arange(4000)
    base = 50.0 * np.sin(2 * np.pi * k / 1000)
    for wiggle, extra in ((8.0, 0), (12.0, 1)):
        x = base.copy()
        x[2480:2520] = wiggle * np.sin(
            2 * np.pi * np.arange(40) / 20
        )  # two wiggles where base ~ 0 going down
        # the wiggle region sits at the reference on the way down: a counted wiggle adds one upward crossing
        assert upward_crossings(x).size == 3 + extra
        # spikes on under 1 % of the samples (at the peaks, in their own direction) leave the range alone
        x[245:255] += 400.0
        x[1745:1755] -= 400.0
        x[3245:3255] += 400.0
        x[3745:3755] -= 400.0
        assert upward_crossings(x).size == 3 + extra


def test_the_reference_is_the_mean_or_the_least_squares_line() -> None:
    x = np.array([1.0, 3.0, 2.0, 6.0])
    np.testing.assert_allclose(reference_level(x, "mean"), 3.0)
    slope, intercept = np.polyfit(np.arange(4.0), x, 1)
    np.testing.assert_allclose(reference_level(x, "linear"), intercept + slope * np.arange(4.0))
    assert slope == pytest.approx(1.4)


def test_without_hysteresis_reaching_the_reference_counts_as_crossing_it() -> None:
    x = np.array([-1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 3.0])  # mean 0: touches the reference three times
    assert x.mean() == 0.0
    assert upward_crossings(x, hysteresis_deg=0.0).tolist() == [1, 3, 5]
