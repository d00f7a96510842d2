"""Model prediction across configurations: a fit on one configuration predicts another
with the same elements at another speed, and the protocol declares the pairs; a prediction onto angles
wider than those the model was fitted on is flagged as extrapolated, and its numbers still reported."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import fit_configuration
from protocol_runner.analysis.service import bouc_wen_result
from protocol_runner.archive.model_results import write_predictions
from protocol_runner.archive.results import bouc_wen_fill
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate
from protocol_runner.report.predictions import AngleRanges, declared_pairs, prediction_row, predictions

STABLE = BoucWenParams(A=0.3, n=1.2, beta=(0.05, 0.0, 0.0, 0.0, 0.0, 0.03))
PROTOCOL = """
report:
  predictions:
    - {fit: 1, predict: 2, note: "half speed"}
    - {fit: 1, predict: 3}
"""


def loops(
    period_s: float, rate_hz: float = 50.0, amplitude_deg: float = 50.0
) -> list[tuple[np.ndarray, np.ndarray]]:
    t = np.arange(0.0, 3.25 * period_s, 1.0 / rate_hz)
    x = amplitude_deg * np.sin(2.0 * np.pi * t / period_s)
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


def test_a_prediction_onto_wider_angles_is_flagged_and_still_reported(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Configuration 1 swings +-20 deg, 2 swings +-50 deg. The Bouc-Wen model fitted on 1 runs 30 deg
    beyond its angles on 2's loops: extrapolated, its (true, poor) RMSE kept; fitted on 2 it predicts 1
    within its angles: not extrapolated. The archive's /predictions records both ranges and the flag."""
    archive = tmp_path / "archive.h5"
    with h5py.File(archive, "w") as f:
        for name, amplitude in (("config_01", 20.0), ("config_02", 50.0)):
            segments = loops(8.0, amplitude_deg=amplitude)
            result, _ = fit_configuration(segments, starts=2, cross_validate_trials=False)
            bouc_wen_fill(name, bouc_wen_result(result, segments, []))(f)
    narrow_to_wide, wide_to_narrow = predictions(
        archive, "report: {predictions: [{fit: 1, predict: 2}, {fit: 2, predict: 1}]}"
    )
    r = narrow_to_wide.bouc_wen_ranges
    assert r is not None and r.extrapolated
    assert r.source_deg == pytest.approx((-20.0, 20.0), abs=0.5)
    assert r.target_deg == pytest.approx((-50.0, 50.0), abs=0.5)
    assert r.beyond_source_deg == pytest.approx(30.0, abs=1.0)
    assert np.isfinite(narrow_to_wide.rmse_nm) and narrow_to_wide.reason == ""
    note = narrow_to_wide.extrapolation_note
    assert "Bouc-Wen model runs 30." in note and "polynomial fitted on 1's angles" in note
    assert "element model" not in note  # no element model was fitted: nothing said of it
    back = wide_to_narrow.bouc_wen_ranges
    assert back is not None and not back.extrapolated and back.beyond_source_deg == 0.0
    assert wide_to_narrow.extrapolation_note == ""

    with h5py.File(archive, "a") as f:
        write_predictions(f, [prediction_row(p) for p in (narrow_to_wide, wide_to_narrow)])
    with h5py.File(archive, "r") as f:
        flagged, within = f["predictions/from_1_to_2"].attrs, f["predictions/from_2_to_1"].attrs
        assert bool(flagged["bouc_wen_extrapolated"]) and not bool(within["bouc_wen_extrapolated"])
        assert list(flagged["bouc_wen_source_range_deg"]) == list(r.source_deg)
        assert list(flagged["bouc_wen_target_range_deg"]) == list(r.target_deg)
        assert float(flagged["bouc_wen_beyond_source_deg"]) == r.beyond_source_deg
        assert "element_extrapolated" not in flagged  # no element model: its range does not exist


def test_reaching_a_little_beyond_the_fitted_angles_is_not_extrapolating() -> None:
    """The threshold is 5 % of A's span, on the side where B reaches farther."""
    assert AngleRanges((0.0, 100.0), (-4.0, 103.0)).beyond_source_deg == 4.0
    assert not AngleRanges((0.0, 100.0), (-4.0, 103.0)).extrapolated
    assert AngleRanges((0.0, 100.0), (10.0, 106.0)).extrapolated
