"""Facts about the element fit (analysis/element_fit.py) on small noise-free loops: a torsion spring and a
bungee cord under a Coulomb friction of +-2 N*m, swept +-45 deg about 65 deg.  The midline cancels the
friction; the fit finds a cord declared slack over the whole range; at least one more point than parameters
is needed; the default trim is 5 deg at each end (thesis §6.1.6: rounded loop corners)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from protocol_runner.analysis.element_fit import branch_midline, fit_elements, model_torque_nm
from protocol_runner.analysis.validation import AnalysisError
from protocol_runner.models.elements import build_device


def torsion(k: float, neutral: float) -> tuple[str, str, dict]:
    return ("torsion", "torsion_spring", {"stiffness_nm_per_deg": k, "neutral_deg": neutral})


def cord(k: float, slack: float) -> tuple[str, str, dict]:
    return ("cord", "bungee", {"stiffness_nm_per_deg": k, "slack_deg": slack, "direction": 1})


TRUE = [torsion(0.3, 40.0), cord(0.6, 75.0)]


def loop() -> tuple[np.ndarray, np.ndarray]:
    t = np.arange(0.0, 24.0, 2e-3)
    angle = 65.0 + 45.0 * np.sin(2.0 * np.pi * t / 6.0)
    friction = 2.0 * np.sign(np.cos(2.0 * np.pi * t / 6.0))
    return angle, model_torque_nm(build_device(TRUE), angle) + friction


def test_a_cord_declared_slack_over_the_whole_range_is_still_found() -> None:
    """Declared slack at 150 deg, the cord gives no torque anywhere in 20-110 deg: no gradient moves it
    from there, so the angle parameters must also start inside the data's range."""
    angle, torque = loop()
    fit = fit_elements(angle, torque, [torsion(0.1, 0.0), cord(0.2, 150.0)])
    assert fit.value("cord", "slack_deg") == pytest.approx(75.0, abs=0.1)
    assert fit.value("cord", "stiffness_nm_per_deg") == pytest.approx(0.6, rel=1e-3)
    assert fit.value("torsion", "stiffness_nm_per_deg") == pytest.approx(0.3, rel=1e-3)
    assert fit.rmse_nm < 0.01


def test_the_target_named_in_a_protocol_file_selects_the_midline() -> None:
    """A target string read from a file is a new string object, equal to "branch_mean" but not the same
    object: it must still select the midline, whose fit cancels the friction (all samples keep +-2 N*m)."""
    angle, torque = loop()
    target = "".join(["branch", "_mean"])
    fit = fit_elements(angle, torque, [torsion(0.1, 0.0), cord(0.2, 60.0)], target=target)  # type: ignore[arg-type]
    assert fit.reason == "least squares on the loop midline"
    assert fit.rmse_nm < 0.01
    assert fit.rmse_all_samples_nm == pytest.approx(2.0, abs=0.01)  # the friction, on every sample


def test_by_default_five_degrees_are_left_out_at_each_end_of_the_midline() -> None:
    angle, torque = loop()
    whole, _ = branch_midline(angle, torque, trim_deg=0.0)
    fit = fit_elements(angle, torque, [torsion(0.1, 0.0), cord(0.2, 60.0)])
    assert fit.curve_angle_deg[0] == pytest.approx(whole[0] + 5.0)
    assert whole[-1] - 6.0 < fit.curve_angle_deg[-1] <= whole[-1] - 5.0


def test_the_branches_must_share_a_range_after_the_trim() -> None:
    angle, torque = loop()  # the branches share about 20-110 deg
    assert branch_midline(angle, torque, trim_deg=40.0)[0].size > 0
    with pytest.raises(AnalysisError, match="share no angle range"):
        branch_midline(angle, torque, trim_deg=50.0)
    with pytest.raises(AnalysisError, match="trim must be >= 0"):
        branch_midline(angle, torque, trim_deg=-1.0)


def test_a_fit_needs_more_points_than_parameters() -> None:
    """Four parameters (two per element) on a loop that visits four angles only: refused; five angles
    are enough."""
    for n_angles, enough in ((4, False), (5, True)):
        levels = np.linspace(30.0, 100.0, n_angles)
        angle = np.tile(np.concatenate([levels, levels[::-1]]), 3)
        torque = model_torque_nm(build_device(TRUE), angle)
        device = [torsion(0.1, 0.0), cord(0.2, 60.0)]
        if enough:
            fit = fit_elements(angle, torque, device, target="all_samples")
            assert fit.applicable and fit.curve_angle_deg.size == 5
        else:
            with pytest.raises(AnalysisError, match="only 4 points to fit 4 element parameters"):
                fit_elements(angle, torque, device, target="all_samples")


def test_a_device_with_nothing_elastic_is_not_applicable_whatever_the_loop() -> None:
    brake = [("brake", "coulomb_brake", {"torque_nm": 2.0})]
    fit = fit_elements([10.0, 20.0], [1.0, -1.0], brake)
    assert not fit.applicable and fit.reason.startswith("not applicable: the device has no elastic element")


def test_the_all_samples_fit_is_the_least_squares_fit_to_every_sample() -> None:
    """Condensing the samples into 0.05 deg bins weighted by their counts must leave the optimum where a
    least-squares fit to every sample puts it, also for a cord whose kink lies inside a bin; and the RMSE
    reported for every sample is the RMS residual of every sample."""
    angle, with_torsion = loop()
    # the cord alone, with the friction and noise
    torque = with_torsion - model_torque_nm(build_device(TRUE[:1]), angle)
    torque += np.random.default_rng(4).normal(0.0, 0.5, angle.shape)
    declared = [cord(0.2, 60.0)]
    fit = fit_elements(angle, torque, declared, target="all_samples")

    def residual(x: np.ndarray) -> np.ndarray:
        return model_torque_nm(build_device([cord(x[0], x[1])]), angle) - torque

    direct = least_squares(residual, [0.2, 60.0], bounds=([0.0, -720.0], [1e4, 720.0]))
    assert fit.value("cord", "stiffness_nm_per_deg") == pytest.approx(direct.x[0], rel=1e-5)
    assert fit.value("cord", "slack_deg") == pytest.approx(direct.x[1], abs=1e-3)
    rms = float(np.sqrt(np.mean(residual(np.array([v for _, _, v in fit.fitted])) ** 2)))
    assert fit.rmse_all_samples_nm == pytest.approx(rms, rel=1e-9)
    assert fit.rmse_nm == fit.rmse_all_samples_nm
