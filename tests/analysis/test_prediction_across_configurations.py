"""Model prediction across configurations: a fit on one configuration predicts another
with the same elements at another speed, and the protocol declares the pairs."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import fit_configuration
from protocol_runner.analysis.service import bouc_wen_result
from protocol_runner.archive.results import bouc_wen_fill
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate
from protocol_runner.report.predictions import declared_pairs, predictions

STABLE = BoucWenParams(A=0.3, n=1.2, beta=(0.05, 0.0, 0.0, 0.0, 0.0, 0.03))
PROTOCOL = """
report:
  predictions:
    - {fit: 1, predict: 2, note: "half speed"}
    - {fit: 1, predict: 3}
"""


def loops(period_s: float, rate_hz: float = 50.0) -> list[tuple[np.ndarray, np.ndarray]]:
    t = np.arange(0.0, 3.25 * period_s, 1.0 / rate_hz)
    x = 50.0 * np.sin(2.0 * np.pi * t / period_s)
    rng = np.random.default_rng(int(period_s))
    return [(x, 0.2 * x + simulate(x, STABLE, 0.0) + 0.05 * rng.standard_normal(x.size)) for _ in range(2)]


def test_a_fit_predicts_the_same_joint_at_half_speed(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """The joint is rate-independent, so the configuration fitted at full speed predicts the half-speed one
    (twice the samples per cycle) about as well as that configuration's own fit; configuration 3 was not
    fitted, which the prediction says."""
    archive = tmp_path / "archive.h5"
    with h5py.File(archive, "w") as f:
        for name, segments in (("config_01", loops(8.0)), ("config_02", loops(16.0))):
            result, _ = fit_configuration(segments, starts=2, cross_validate_trials=False)
            bouc_wen_fill(name, bouc_wen_result(result, segments, []))(f)
    assert declared_pairs(PROTOCOL) == [(1, 2, "half speed"), (1, 3, "")]
    first, missing = predictions(archive, PROTOCOL)
    assert (first.fit_key, first.predict_key) == (1, 2) and first.reason == ""
    assert first.rmse_nm == pytest.approx(first.own_rmse_nm, rel=0.05)
    assert missing.reason == "no fit of 3" and np.isnan(missing.rmse_nm)


def test_no_declared_pairs_no_predictions(tmp_path) -> None:  # type: ignore[no-untyped-def]
    assert predictions(tmp_path / "absent.h5", "name: x\n") == ()
    assert declared_pairs("report: {predictions: [{fit: a, predict: 2}]}") == []
