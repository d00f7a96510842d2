"""Facts about the elements backbone (analysis/elastic_backbone.py), on small noise-free loops: a linear
torsion spring k (angle - neutral) plus a Coulomb friction of +-2 N*m (which the loop midline cancels).
In the centred coordinates of the Bouc-Wen fit, g(x) = G(x + a) - c with a the trials' mean angle and c the
spring's mean torque over their samples, so for a linear spring g(x) = k x: zero at the mean angle."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.elastic_backbone import elements_backbone_factory

DECLARED = [("torsion", "torsion_spring", {"stiffness_nm_per_deg": 0.1, "neutral_deg": 0.0})]
CENTRED_DEG = np.linspace(-40.0, 40.0, 9)


def loop(
    stiffness: float, mean_deg: float = 65.0, neutral_deg: float = 40.0
) -> tuple[np.ndarray, np.ndarray]:
    """Two cycles of +-45 deg about `mean_deg`, from a minimum: spring torque plus +-2 N*m friction."""
    t = np.arange(0.0, 12.0, 0.02)
    angle = mean_deg - 45.0 * np.cos(2.0 * np.pi * t / 6.0)
    friction = 2.0 * np.sign(np.sin(2.0 * np.pi * t / 6.0))
    return angle, stiffness * (angle - neutral_deg) + friction


def test_the_backbone_is_the_fitted_spring_centred_at_the_trials_mean_angle() -> None:
    """The declared spring is wrong (0.1 N*m/deg, neutral 0 deg); the trials come from 0.3 N*m/deg with
    neutral 40 deg, about mean angles 60 and 70 deg (a = 65): g(x) = 0.3 x, zero at the mean angle."""
    g = elements_backbone_factory([loop(0.3, 60.0), loop(0.3, 70.0)], DECLARED)([0, 1])
    assert g.kind == "elements"
    np.testing.assert_allclose(g(CENTRED_DEG), 0.3 * CENTRED_DEG, rtol=1e-3, atol=1e-6)
    assert "torsion.stiffness_nm_per_deg = 0.3" in g.note and "torsion.neutral_deg = 40" in g.note
    assert "centred at 65 deg" in g.note


def test_the_backbone_is_fitted_on_the_given_trials_only() -> None:
    """Trial 0 from a 0.3 N*m/deg spring, trial 1 from a 0.6 one: each index gives its own spring (a trial
    held out of a fit never enters its backbone)."""
    build = elements_backbone_factory([loop(0.3), loop(0.6)], DECLARED)
    np.testing.assert_allclose(build([0])(CENTRED_DEG), 0.3 * CENTRED_DEG, atol=1e-6)
    np.testing.assert_allclose(build([1])(CENTRED_DEG), 0.6 * CENTRED_DEG, atol=1e-6)


def test_undefined_torque_samples_are_left_out_with_their_angles() -> None:
    angle, torque = loop(0.3)
    holed = torque.copy()
    holed[::7] = np.nan
    g = elements_backbone_factory([(angle, holed)], DECLARED)([0])
    assert g.kind == "elements"
    np.testing.assert_allclose(g(CENTRED_DEG), 0.3 * CENTRED_DEG, atol=1e-6)


def test_with_nothing_to_fit_g_is_zero_and_the_note_says_why() -> None:
    angle, torque = loop(0.3)
    ramp = np.linspace(0.0, 90.0, 300)
    cases = [
        (elements_backbone_factory([(angle, torque)], DECLARED), [], "not applicable: no trial"),
        # the element fit cannot use a trial without an unloading branch (an AnalysisError)
        (elements_backbone_factory([(ramp, 0.3 * ramp)], DECLARED), [0], "not applicable: the trial has no"),
        (
            elements_backbone_factory([(angle, torque)], [("brake", "coulomb_brake", {"torque_nm": 2.0})]),
            [0],
            "not applicable: the device has no elastic element",
        ),
    ]
    for build, indices, reason in cases:
        g = build(indices)
        assert g.kind == "none" and g.note.startswith(reason), g.note
        assert np.all(g(CENTRED_DEG) == 0.0)


def test_a_spring_with_no_free_parameter_is_used_as_declared_and_says_so() -> None:
    declared = [("torsion", "torsion_spring", {"stiffness_nm_per_deg": 0.3, "neutral_deg": 40.0, "fit": []})]
    g = elements_backbone_factory([loop(0.3)], declared)([0])
    assert g.kind == "elements" and "(no free parameter)" in g.note
    np.testing.assert_allclose(g(CENTRED_DEG), 0.3 * CENTRED_DEG, atol=1e-9)


@pytest.mark.parametrize("stiffness", [0.3, 0.6])
def test_the_backbone_has_zero_mean_over_the_centred_samples(stiffness: float) -> None:
    """g is centred like the torque: its mean over the fitted trial's centred angles is zero."""
    angle, torque = loop(stiffness, 50.0)
    g = elements_backbone_factory([(angle, torque)], DECLARED)([0])
    assert float(np.mean(g(angle - angle.mean()))) == pytest.approx(0.0, abs=1e-9)
