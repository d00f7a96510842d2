"""Facts of the elastic backbone ``torque = g(angle) + z`` (models/bouc_wen/backbone.py): the least-squares
polynomial through every sample is the loop's midline, reproduces a polynomial torque exactly, and continues
along its end tangent beyond the fitted range."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.backbone import (
    MAX_DEGREE,
    Backbone,
    FixedBackbone,
    fit_backbone,
    hysteretic_part,
    zero_backbone,
)


def _cubic_nm(angle_deg: np.ndarray) -> np.ndarray:
    return 2.0 + 0.3 * angle_deg - 0.01 * angle_deg**2 + 2e-4 * angle_deg**3


def test_a_polynomial_torque_of_at_most_the_degree_is_reproduced_exactly() -> None:
    """Least squares through noise-free samples of a cubic, on trials of different angle ranges: g is the
    cubic at every fitted angle (the scale is the largest |angle| of all trials, both signs count)."""
    a = np.linspace(-20.0, 35.0, 41)
    b = np.linspace(-50.0, 10.0, 23)
    backbone = fit_backbone([(a, _cubic_nm(a)), (b, _cubic_nm(b))], degree=3)
    assert backbone.degree == 3
    assert backbone.angle_scale_deg == pytest.approx(50.0)
    for x in (a, b):
        np.testing.assert_allclose(backbone(x), _cubic_nm(x), rtol=0.0, atol=1e-9)


def test_the_default_degree_is_nine() -> None:
    """The module notes: degree 9 by default, so a ninth-degree torque is reproduced and a tenth is not."""
    x = np.linspace(-1.0, 1.0, 200)
    backbone = fit_backbone([(x, x**9)])
    assert backbone.degree == 9
    np.testing.assert_allclose(backbone(x), x**9, atol=1e-9)
    assert np.max(np.abs(fit_backbone([(x, x**10)])(x) - x**10)) > 1e-3


def test_the_backbone_of_a_symmetric_loop_is_its_midline_and_encloses_no_energy() -> None:
    """Loading branch p(x) + c and unloading branch p(x) - c on the same angles: the least-squares curve
    runs midway, g = p, and its loop integral (energy) is zero while the data's is 2 c (x_max - x_min)."""
    x_up = np.linspace(-30.0, 30.0, 121)
    x_down = x_up[::-1]
    c = 1.5
    x = np.concatenate([x_up, x_down])
    y = np.concatenate([_cubic_nm(x_up) + c, _cubic_nm(x_down) - c])
    backbone = fit_backbone([(x, y)], degree=5)
    np.testing.assert_allclose(backbone(x_up), _cubic_nm(x_up), atol=1e-9)
    closed = np.append(x, x[0])
    g = backbone(closed)
    energy_g = float(np.sum(0.5 * (g[1:] + g[:-1]) * np.diff(closed)))
    assert energy_g == pytest.approx(0.0, abs=1e-9)
    ((_, z),) = hysteretic_part([(x, y)], backbone)
    np.testing.assert_allclose(z, np.concatenate([np.full(121, c), np.full(121, -c)]), atol=1e-9)


def test_beyond_the_fitted_range_the_backbone_continues_along_its_end_tangents() -> None:
    """g = x^2 fitted on [-10, 10]: at 20 deg the tangent at 10 gives 100 + 20 * 10 = 300, at -20 the
    tangent at -10 gives 100 + (-20) * (-10) = 300; inside, g is x^2 itself."""
    x = np.linspace(-10.0, 10.0, 41)
    backbone = fit_backbone([(x, x**2)], degree=2)
    assert backbone(np.array([20.0, -20.0, 5.0, -10.0])) == pytest.approx([300.0, 300.0, 25.0, 100.0])
    assert backbone(15.0) == pytest.approx(100.0 + 20.0 * 5.0)


def test_a_constant_backbone_stays_constant_beyond_its_range() -> None:
    backbone = Backbone(coef=(4.0,), angle_scale_deg=10.0)
    assert backbone.degree == 0
    np.testing.assert_allclose(backbone(np.array([-30.0, 0.0, 30.0])), [4.0, 4.0, 4.0])


def test_the_degree_must_be_an_integer_from_0_to_the_maximum() -> None:
    x = np.linspace(-5.0, 5.0, 40)
    segments = [(x, 0.5 * x)]
    assert fit_backbone(segments, degree=0).coef == pytest.approx((0.0,), abs=1e-12)
    assert fit_backbone(segments, degree=MAX_DEGREE).degree == MAX_DEGREE == 15
    for bad in (-1, MAX_DEGREE + 1, 2.0):
        with pytest.raises(InvalidInput, match="backbone degree must be an integer from 0 to 15"):
            fit_backbone(segments, degree=bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("angle", [np.zeros(10), np.full(10, np.inf), np.array([1.0, np.nan, 2.0])])
def test_an_angle_without_a_finite_nonzero_range_cannot_give_a_backbone(angle: np.ndarray) -> None:
    with pytest.raises(InvalidInput, match="no backbone can be fitted"):
        fit_backbone([(angle, np.ones(angle.size))])


def test_no_samples_cannot_give_a_backbone() -> None:
    with pytest.raises(InvalidInput, match="no backbone can be fitted"):
        fit_backbone([(np.zeros(0), np.zeros(0))])


def test_a_fixed_backbone_is_its_function_at_the_given_angles_in_their_shape() -> None:
    """A given g: its value at each angle, a constant broadcast to the angles' shape; g = 0 records why."""
    spring = FixedBackbone(torque_nm=lambda x: 0.2 * (x - 10.0), note="a torsion spring")
    np.testing.assert_allclose(spring(np.array([10.0, 20.0, -10.0])), [0.0, 2.0, -4.0])
    assert spring.kind == "elements" and spring.note == "a torsion spring"
    constant = FixedBackbone(torque_nm=lambda x: 3.0)
    out = constant(np.array([[1.0, 2.0], [3.0, 4.0]]))
    assert out.shape == (2, 2) and np.all(out == 3.0) and out.flags.c_contiguous
    out[0, 0] = 0.0  # a fresh array, writable
    zero = zero_backbone("no elastic element")
    assert zero.kind == "none" and zero.note == "no elastic element"
    np.testing.assert_array_equal(zero(np.array([-5.0, 5.0])), [0.0, 0.0])


def test_the_hysteretic_part_is_each_trials_torque_minus_the_backbone() -> None:
    spring = FixedBackbone(torque_nm=lambda x: 0.5 * x)
    x1, x2 = np.array([0.0, 2.0, 4.0]), np.array([-2.0, 0.0])
    parts = hysteretic_part([(x1, np.array([1.0, 2.0, 3.0])), (x2, np.array([0.0, 0.0]))], spring)
    assert len(parts) == 2
    assert parts[0][0] is x1 and parts[1][0] is x2
    np.testing.assert_allclose(parts[0][1], [1.0, 1.0, 1.0])
    np.testing.assert_allclose(parts[1][1], [1.0, 0.0])
