"""The Bouc-Wen backbone from the device's elastic elements: torque = g(angle) + z with
g the element fit's springs, held fixed while z is fitted.

Data: a known torsion spring and bungee (the elastic torque G of the absolute angle) plus a known
Bouc-Wen hysteresis z (a friction-like loop, thesis Eq 20-22), three trials with 0.2 N*m noise; the device
is declared with wrong spring values, so the element fit has to estimate them."""

from __future__ import annotations

import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import centred_loop, fit_loops
from protocol_runner.analysis.elastic_backbone import elements_backbone_factory
from protocol_runner.analysis.element_fit import model_torque_nm
from protocol_runner.archive.results import backbone_attrs
from protocol_runner.models.bouc_wen.backbone import FixedBackbone
from protocol_runner.models.bouc_wen.fitting import cross_validate
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate
from protocol_runner.models.elements import build_device
from protocol_runner.protocol.schema import BoucWenFitSpec

NOISE_NM = 0.2
MEAN_ANGLE_DEG = 65.0
TRUE = BoucWenParams(A=2.0, n=1.0, beta=(0.5, 0.0, 0.0, 0.0, 0.0, 0.0))  # z saturates at A / beta1 = 4 N*m


def device(torsion: tuple[float, float], cord: tuple[float, float]) -> list:
    return [
        ("torsion", "torsion_spring", {"stiffness_nm_per_deg": torsion[0], "neutral_deg": torsion[1]}),
        ("cord", "bungee", {"stiffness_nm_per_deg": cord[0], "slack_deg": cord[1], "direction": 1}),
        ("brake", "coulomb_brake", {"torque_nm": 2.0, "transition_deg": 1.5}),
    ]


TRUE_DEVICE = device((0.3, 40.0), (0.6, 75.0))
DECLARED = device((0.1, 0.0), (0.2, 60.0))  # wrong: the element fit must find the true values


def trials(n: int = 3) -> list[tuple[np.ndarray, np.ndarray]]:
    """Two full cycles of +-45 deg about 65 deg per trial, started on the loop (so z has zero mean)."""
    t = np.arange(0.0, 12.0, 5e-3)
    centred = -45.0 * np.cos(2 * np.pi * t / 6.0)
    z = simulate(centred, TRUE, z0=-4.0)
    angle = MEAN_ANGLE_DEG + centred
    elastic = model_torque_nm(build_device(TRUE_DEVICE), angle)
    rng = np.random.default_rng(7)
    return [(angle, elastic + z + rng.normal(0.0, NOISE_NM, t.shape)) for _ in range(n)]


@pytest.fixture(scope="module")
def data() -> tuple[list, list]:
    raw = trials()
    return raw, [centred_loop(a, y) for a, y in raw]


@pytest.fixture(scope="module")
def elements_fit(data: tuple[list, list]):
    raw, segments = data
    return fit_loops(segments, starts=8, cross_validated=True, backbone_degree=None, elements=(raw, DECLARED))


def test_the_elements_backbone_recovers_the_bouc_wen_parameters_within_their_intervals(elements_fit) -> None:
    result, _ = elements_fit
    true = TRUE.as_array()
    low, high = np.asarray(result.param_interval_low), np.asarray(result.param_interval_high)
    assert np.all((low <= true) & (true <= high)), (low, true, high)
    assert pytest.approx(TRUE.A, rel=0.05) == result.params.A
    assert result.params.beta[0] == pytest.approx(TRUE.beta[0], rel=0.15)
    assert not result.weakly_identified


def test_the_elements_backbone_fit_is_at_the_noise_level_in_and_out_of_sample(elements_fit) -> None:
    result, cv = elements_fit
    assert result.rmse_nm == pytest.approx(NOISE_NM, rel=0.05)
    assert len(cv) == 3 and all(v == pytest.approx(NOISE_NM, rel=0.05) for v in cv)


def test_the_backbone_is_the_fitted_springs_centred_like_the_loops(elements_fit) -> None:
    result, _ = elements_fit
    backbone = result.backbone
    assert isinstance(backbone, FixedBackbone) and backbone.kind == "elements"
    assert "torsion.stiffness_nm_per_deg = 0.30" in backbone.note
    x = np.linspace(-40.0, 40.0, 81)
    springs = model_torque_nm(build_device(TRUE_DEVICE), MEAN_ANGLE_DEG + x)
    g = backbone(x)
    # the same curve up to the centring constant, within the noise
    assert np.max(np.abs((g - g.mean()) - (springs - springs.mean()))) < NOISE_NM
    attrs = backbone_attrs(result)
    assert attrs["backbone"] == "elements" and attrs["backbone_note"] == backbone.note
    grid = np.asarray(attrs["backbone_grid_angle_deg"])
    assert np.allclose(attrs["backbone_grid_torque_nm"], backbone(grid))


def test_without_the_backbone_the_same_data_fit_worse(data, elements_fit) -> None:
    _, segments = data
    thesis, cv = fit_loops(segments, starts=8, cross_validated=True, backbone_degree=None)
    assert thesis.backbone is None
    assert thesis.rmse_nm > 4.0 * elements_fit[0].rmse_nm
    assert min(cv) > 4.0 * max(elements_fit[1])


def test_a_device_with_no_elastic_element_gives_g_zero_and_says_why(data) -> None:
    raw, segments = data
    brake_only = [DECLARED[2]]
    result, _ = fit_loops(
        segments, starts=2, cross_validated=False, backbone_degree=None, elements=(raw, brake_only)
    )
    thesis, _ = fit_loops(segments, starts=2, cross_validated=False, backbone_degree=None)
    attrs = backbone_attrs(result)
    assert attrs["backbone"] == "none"
    assert str(attrs["backbone_note"]).startswith("not applicable: the device has no elastic element")
    assert result.rmse_nm == pytest.approx(thesis.rmse_nm, rel=1e-9)  # torque = z, as the thesis form


def test_a_held_out_trial_never_enters_its_own_backbone(data) -> None:
    raw, segments = data
    build = elements_backbone_factory(raw, DECLARED)
    seen: list[tuple[int, ...]] = []

    def spy(indices):
        seen.append(tuple(indices))
        return build(indices)

    cross_validate(segments, starts=1, backbone_factory=spy)
    assert seen == [(1, 2), (0, 2), (0, 1)]


def test_the_protocol_accepts_elements_and_keeps_the_polynomial_default() -> None:
    assert BoucWenFitSpec().backbone == "polynomial"
    spec = BoucWenFitSpec(backbone="elements")
    assert spec.polynomial_degree is None
    with pytest.raises(ValueError, match="backbone"):
        BoucWenFitSpec(backbone="springs")
