"""The angle bins of the branch curves (analysis/branches.py): one point per occupied bin, in increasing
angle order, each the mean angle and mean torque of the samples in that bin."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis import branches


@pytest.mark.parametrize("bin_width_deg", [0.05, 0.5, 1.0])
def test_each_occupied_bin_gives_the_mean_of_its_samples(bin_width_deg: float) -> None:
    rng = np.random.default_rng(11)
    angle = np.concatenate([rng.uniform(-20.0, 130.0, 3000), np.round(rng.normal(40.0, 25.0, 2000), 2)])
    torque = rng.normal(0.0, 30.0, angle.size)
    mean_angle, mean_torque = branches._binned_curve(angle, torque, bin_width_deg)
    bins = np.floor(angle / bin_width_deg)
    occupied = np.unique(bins)
    assert mean_angle.shape == mean_torque.shape == (occupied.size,)
    assert np.all(np.diff(mean_angle) > 0)  # in increasing angle order
    for k in rng.choice(occupied.size, 25, replace=False):
        inside = bins == occupied[k]
        assert mean_angle[k] == pytest.approx(np.mean(angle[inside]), rel=1e-12)
        assert mean_torque[k] == pytest.approx(np.mean(torque[inside]), rel=1e-12, abs=1e-12)
