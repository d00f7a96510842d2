"""Facts about the Bouc-Wen fit of a configuration's centred loops (analysis/bouc_wen_fit.py): the centred loop has
zero mean angle and torque and drops undefined torque samples; the backbone is the device's elastic
elements when asked (whatever polynomial degree is set), zero when the element fit is disabled, and the
polynomial midline otherwise."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import centred_loop, fit_loops
from protocol_runner.models.bouc_wen.backbone import Backbone, FixedBackbone

from .synthetic_loops import SPRING, spring_and_loop_trials


def test_a_centred_loop_has_zero_mean_and_drops_undefined_torques_with_their_angles() -> None:
    angle = np.array([10.0, 20.0, 30.0, 40.0, 50.0])
    torque = np.array([1.0, np.nan, 3.0, 5.0, np.inf])
    a, t = centred_loop(angle, torque)
    np.testing.assert_allclose(a, np.array([10.0, 30.0, 40.0]) - 80.0 / 3.0)
    np.testing.assert_allclose(t, [-2.0, 0.0, 2.0])


@pytest.fixture(scope="module")
def segments() -> list[tuple[np.ndarray, np.ndarray]]:
    return [centred_loop(a, t) for a, t in spring_and_loop_trials()]


def _fit_with_device(segments, device):
    """The loops fitted with the element backbone of `device` (None: the element fit is disabled)."""
    return fit_loops(
        segments,
        starts=1,
        cross_validated=False,
        backbone_degree=9,
        elements=(spring_and_loop_trials(), device),
    )[0]


def test_the_elements_backbone_replaces_the_polynomial(segments) -> None:
    result = _fit_with_device(segments, SPRING)
    assert isinstance(result.backbone, FixedBackbone) and result.backbone.kind == "elements"
    x = np.linspace(-40.0, 40.0, 9)
    np.testing.assert_allclose(result.backbone(x), 0.3 * x, rtol=0.01, atol=1e-9)  # the spring, centred


def test_a_disabled_element_fit_gives_g_zero_and_says_so(segments) -> None:
    result = _fit_with_device(segments, None)
    assert isinstance(result.backbone, FixedBackbone) and result.backbone.kind == "none"
    assert result.backbone.note == "not applicable: the element fit is disabled"
    assert np.all(result.backbone(np.linspace(-40.0, 40.0, 9)) == 0.0)


def test_without_elements_the_backbone_is_the_polynomial_of_the_given_degree_or_none(segments) -> None:
    poly, _ = fit_loops(segments, starts=1, cross_validated=False, backbone_degree=3)
    assert isinstance(poly.backbone, Backbone) and poly.backbone.degree == 3
    thesis, cv = fit_loops(segments, starts=1, cross_validated=True, backbone_degree=None)
    assert thesis.backbone is None and len(cv) == 2
