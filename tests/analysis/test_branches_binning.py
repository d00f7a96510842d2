"""The angle bins of the branch curves (analysis/branches.py) counted directly give bit for bit what sorting
the bin numbers gives (a stored value must not depend on how the bins are counted)."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis import branches


@pytest.mark.parametrize("bin_width_deg", [0.05, 0.5, 1.0])
def test_direct_bins_are_the_sorted_bins(bin_width_deg: float, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(11)
    angle = np.concatenate([rng.uniform(-20.0, 130.0, 3000), np.round(rng.normal(40.0, 25.0, 2000), 2)])
    torque = rng.normal(0.0, 30.0, angle.size)
    direct = branches._binned_curve(angle, torque, bin_width_deg)
    monkeypatch.setattr(branches, "DIRECT_BINS_MAX", -1)  # force the sorting path
    by_sorting = branches._binned_curve(angle, torque, bin_width_deg)
    assert all(np.array_equal(d, s) for d, s in zip(direct, by_sorting, strict=True))
    assert np.all(np.diff(direct[0]) > 0)  # one point per occupied bin, in increasing angle order
    occupied = np.unique(np.floor(angle / bin_width_deg)).size
    assert direct[0].shape == direct[1].shape == (occupied,)
