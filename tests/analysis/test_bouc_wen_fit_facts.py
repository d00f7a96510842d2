"""Facts about the configuration-level Bouc-Wen fit (analysis/bouc_wen_fit.py): the physical constraint
"the model dissipates where the data do", the model torque started at each trial's first torque (with and
without an elastic backbone), the loop energy pooled over every complete cycle, and the cross-validation
that needs at least two trials.  Small synthetic trials: every fit here takes well under a second."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import (
    LoopEnergy,
    fit_configuration,
    fit_loops,
    loop_energy,
    model_torques,
)
from protocol_runner.models.bouc_wen.backbone import Backbone, FixedBackbone
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.records import BoucWenFit
from protocol_runner.models.bouc_wen.simulation import simulate

# saturates on loading in every phase: a stable loop from any state (as in test_bouc_wen_evidence.py)
STABLE = BoucWenParams(A=0.3, n=1.2, beta=(0.05, 0.0, 0.0, 0.0, 0.0, 0.03))
PERIOD_S = 8.17
SPRING_NM_PER_DEG = 0.4


def sinusoid(periods: float, rate_hz: float = 12.5) -> np.ndarray:
    t = np.arange(0.0, periods * PERIOD_S, 1.0 / rate_hz)
    return 60.0 * np.sin(2.0 * np.pi * t / PERIOD_S)


def trials(n: int) -> list[tuple[np.ndarray, np.ndarray]]:
    x = sinusoid(2)
    rng = np.random.default_rng(3)
    return [(x, simulate(x, STABLE, 0.0) + 0.1 * rng.standard_normal(x.size)) for _ in range(n)]


@pytest.fixture(scope="module")
def default_fit() -> tuple[BoucWenFit, list[float]]:
    return fit_configuration(trials(2))


# (model_j, data_j, the model dissipates wherever the data do)
@pytest.mark.parametrize(
    ("model_j", "data_j", "expected"),
    [
        (0.5, 1.0, True),  # both lose energy
        (0.0, 1.0, False),  # the data lose energy, the model none
        (-0.5, 1.0, False),  # the model creates energy where the data lose it
        (math.nan, 1.0, False),  # a diverged model has no loop
        (math.inf, 1.0, False),
        (0.5, 0.5, True),
        (-1.0, 0.5, False),
        (-1.0, 0.0, True),  # lossless data: nothing to dissipate, no constraint
        (-1.0, -0.5, True),
        (-1.0, math.nan, True),  # no complete cycle to tell
    ],
)
def test_the_model_must_dissipate_only_where_the_data_do(
    model_j: float, data_j: float, expected: bool
) -> None:
    assert LoopEnergy(model_j=model_j, data_j=data_j).model_dissipates is expected


def test_by_default_two_trials_are_cross_validated_under_a_degree_9_backbone(default_fit) -> None:
    """The defaults documented for the fit step: one held-out error per trial, torque = g + z with g the
    degree-9 polynomial midline (models/bouc_wen/backbone.py)."""
    result, cv = default_fit
    assert len(cv) == 2 and all(math.isfinite(v) and v > 0.0 for v in cv)
    assert isinstance(result.backbone, Backbone) and result.backbone.degree == 9


def test_one_trial_has_nothing_to_hold_out() -> None:
    result, cv = fit_configuration(trials(1), starts=1, backbone_degree=None)
    assert cv == [] and result.backbone is None


def test_cross_validation_is_skipped_when_not_asked() -> None:
    _, cv = fit_configuration(trials(2), starts=1, cross_validate_trials=False, backbone_degree=None)
    assert cv == []


def test_three_trials_give_three_held_out_errors_at_the_noise_level() -> None:
    _, cv = fit_configuration(trials(3), starts=1, backbone_degree=None)
    assert len(cv) == 3 and all(0.05 < v < 0.3 for v in cv)  # noise 0.1 N*m


def _step_trial() -> tuple[np.ndarray, np.ndarray]:
    x = sinusoid(3.25)
    y = simulate(x, STABLE, 1.5)
    y[1:] += 0.7  # the first torque differs from every later one's start: z0 must be the first sample
    return x, y


def test_the_model_torque_starts_at_each_trials_first_torque() -> None:
    x, y = _step_trial()
    (model,) = model_torques([(x, y)], STABLE)
    assert model[0] == pytest.approx(y[0], abs=1e-12)
    np.testing.assert_allclose(model, simulate(x, STABLE, z0=float(y[0])), atol=1e-12)


def test_with_a_spring_backbone_the_model_is_spring_plus_bouc_wen_started_at_the_first_torque(
    default_fit,
) -> None:
    """torque = g(angle) + z with g a linear spring: the model starts at the trial's first torque, and
    what is left after the spring is the Bouc-Wen state started at the first torque less the spring's."""
    x, y = _step_trial()
    spring = FixedBackbone(torque_nm=lambda a: SPRING_NM_PER_DEG * a + 2.0)
    fit = dataclasses.replace(default_fit[0], params=STABLE, backbone=spring)
    (model,) = model_torques([(x, y)], fit)
    g = SPRING_NM_PER_DEG * x + 2.0
    assert model[0] == pytest.approx(y[0], abs=1e-12)
    np.testing.assert_allclose(model - g, simulate(x, STABLE, z0=float(y[0] - g[0])), atol=1e-12)
    # the spring stores and returns energy: the loop's loss is the Bouc-Wen state's alone
    energy = loop_energy([(x, y)], [model])
    state_only = loop_energy([(x, y)], [model - g])
    assert energy.model_j == pytest.approx(state_only.model_j, rel=1e-9) and energy.model_j > 0.5


def _cycles(n_cycles: int, torque_amplitude_nm: float, rate_hz: float = 400.0) -> tuple[np.ndarray, ...]:
    """n complete cycles (from a minimum, half a period more, so that n upward crossings of the mean pair
    up): an ellipse of angle amplitude 30 deg, area pi * 30 * amplitude deg*N*m per cycle."""
    t = np.arange(0.0, n_cycles + 0.5, 1.0 / rate_hz)
    x = -30.0 * np.cos(2.0 * np.pi * t)
    y = torque_amplitude_nm * np.sin(2.0 * np.pi * t)  # above on loading: a dissipative loop
    return x, y


def _ellipse_j(torque_amplitude_nm: float) -> float:
    return math.pi * 30.0 * torque_amplitude_nm * math.pi / 180.0


def test_the_loop_energy_is_the_mean_over_every_complete_cycle_of_every_trial() -> None:
    """Trial 1: two cycles of area E, trial 2: one of area 2E; the mean per cycle is 4E/3 (not the mean
    of the trials' means, 3E/2).  The model (half the torque) loses half."""
    (x1, y1), (x2, y2) = _cycles(2, 1.0), _cycles(1, 2.0)
    energy = loop_energy([(x1, y1), (x2, y2)], [0.5 * y1, 0.5 * y2])
    e = _ellipse_j(1.0)
    assert energy.data_j == pytest.approx(4.0 * e / 3.0, rel=1e-3)
    assert energy.model_j == pytest.approx(2.0 * e / 3.0, rel=1e-3)
    assert energy.model_dissipates


def test_a_model_that_diverged_on_a_trial_with_cycles_has_no_loop_energy() -> None:
    """A trial without a complete cycle (a ramp) counts for nothing; a model that diverged on a trial that
    has cycles leaves the model's mean energy undefined, whatever the other trials give."""
    ramp = np.linspace(0.0, 30.0, 200)
    x1, y1 = _cycles(2, 1.0)
    x2, y2 = _cycles(2, 1.0)
    diverged = np.full(x1.shape, math.nan)
    segments = [(ramp, 0.1 * ramp), (x1, y1), (x2, y2)]
    energy = loop_energy(segments, [np.full(ramp.shape, math.inf), diverged, 0.5 * y2])
    assert math.isnan(energy.model_j)
    assert energy.data_j == pytest.approx(_ellipse_j(1.0), rel=1e-3)
    assert not energy.model_dissipates
    first_diverged = loop_energy([(x1, y1), (x2, y2)], [diverged, 0.5 * y2])
    assert math.isnan(first_diverged.model_j)


def test_no_trial_or_no_complete_cycle_gives_undefined_energies() -> None:
    for segments in ([], [(np.linspace(0.0, 30.0, 200), np.zeros(200))]):
        energy = loop_energy(segments, [y for _, y in segments])
        assert math.isnan(energy.model_j) and math.isnan(energy.data_j)
        assert energy.model_dissipates  # nothing to tell


def test_every_trial_needs_its_model_torque() -> None:
    x, y = _cycles(2, 1.0)
    with pytest.raises(ValueError):
        loop_energy([(x, y), (x, y)], [y])


def test_with_the_element_fit_disabled_the_backbone_is_zero_and_says_why() -> None:
    """A device given as None (the element fit disabled) fits the thesis form torque = z, whatever
    polynomial degree was asked, and the fit records the reason."""
    data = trials(2)
    fit, _ = fit_loops(data, starts=1, cross_validated=False, backbone_degree=3, elements=(data, None))
    assert isinstance(fit.backbone, FixedBackbone) and fit.backbone.kind == "none"
    assert fit.backbone.note == "not applicable: the element fit is disabled"
    assert np.all(fit.backbone.torque_nm(np.linspace(-60.0, 60.0, 7)) == 0.0)
