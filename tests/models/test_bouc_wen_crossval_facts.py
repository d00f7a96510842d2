"""Facts of leave-one-trial-out cross-validation (models/bouc_wen/fitting.py): it measures the published fit
procedure on trials it never saw, each held-out trial is predicted from its own first torque by a model of
the other trials alone, and a prediction that diverges is scored like the fitter scores one."""

from __future__ import annotations

import inspect
import math

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.backbone import FixedBackbone
from protocol_runner.models.bouc_wen.fitting import cross_validate, fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
PERIOD_S = 8.17


def _sweep(phase: float, amplitude: float = 60.0) -> np.ndarray:
    t = np.arange(0.0, 1.5 * PERIOD_S, 0.05)
    return amplitude * np.sin(2.0 * np.pi * t / PERIOD_S + phase)


def _fig57_trials(count: int) -> list[tuple[np.ndarray, np.ndarray]]:
    xs = [_sweep(0.5 * k) for k in range(count)]
    return [(x, simulate(x, FIG57, 0.0)) for x in xs]


def test_the_held_out_fits_use_the_published_fits_options_by_default() -> None:
    """Cross-validation estimates the error of the fit the report publishes, so every option both take
    (starts, seed, decimation, bounds, scheme) defaults to the same value in both: both take the options as
    one FitKeywords mapping (defaults in one FitOptions record), and the backbone options default alike."""
    cv = inspect.signature(cross_validate).parameters
    full = inspect.signature(fit_trials).parameters
    for params in (cv, full):
        kinds = {name: p.kind for name, p in params.items()}
        assert kinds["options"] is inspect.Parameter.VAR_KEYWORD
    assert "FitKeywords" in str(cv["options"].annotation) and "FitKeywords" in str(full["options"].annotation)
    shared = set(cv) & set(full) - {"segments", "options"}
    assert shared == {"backbone_degree", "backbone_factory"}
    for name in shared:
        assert cv[name].default == full[name].default, name


def test_cross_validation_needs_two_trials_and_gives_one_error_per_trial() -> None:
    trials = _fig57_trials(2)
    with pytest.raises(InvalidInput, match="cross-validation needs at least 2 trials, got 1"):
        cross_validate(trials[:1])
    errors = cross_validate(trials, starts=0)
    assert len(errors) == 2
    assert max(errors) < 0.01  # one noise-free Figure 57 trial predicts the other


def test_the_data_driven_starts_of_the_other_trials_suffice_without_random_ones() -> None:
    """starts=0: each held-out fit starts from the Figure 56 and equation-error guesses computed on the
    other trials, which on noise-free data of one joint reach the joint's parameters."""
    errors = cross_validate(_fig57_trials(3), starts=0)
    assert len(errors) == 3 and max(errors) < 0.01


def test_a_diverging_held_out_prediction_is_held_at_ten_times_the_torque_scale() -> None:
    """Figure 57's (x < 0, dx < 0, z > 0) pattern is unstable: a held-out trial bending further from
    -10 deg with +5 N*m makes the other trials' model (Figure 57) diverge.  Its prediction is then held
    at 10 x the largest |torque| of all the trials, as in the fit (DIVERGENCE_FACTOR), a finite error."""
    trials = _fig57_trials(2)
    x = -10.0 - np.linspace(0.0, 50.0, 101)
    y = np.full(x.size, 5.0)
    trials.append((x, y))
    errors = cross_validate(trials, starts=0)
    bound = 10.0 * max(float(np.max(np.abs(t))) for _, t in trials)
    free = simulate(x, FIG57, 5.0, bound_nm=bound)
    assert np.isnan(free[-1])  # the prediction diverges ...
    held = np.where(np.isnan(free), bound, free)  # ... and is held at +bound from there on
    expected = math.sqrt(float(np.mean((held - y) ** 2)))
    assert expected > 5.0 * max(float(np.max(np.abs(t))) for _, t in trials)
    assert errors[2] == pytest.approx(expected, rel=0.02)


def test_a_backbone_factory_gets_the_other_trials_and_its_g_is_part_of_the_prediction() -> None:
    """Torque = 0.3 N*m/deg * angle (an elastic element) + Figure 57's hysteresis.  The factory is asked
    for the backbone of the other trials' indices only; with g given, each held-out trial is predicted as
    g(angle) + z and the errors vanish.  A g that is wrong by 0.1 N*m/deg leaves the hysteresis to
    absorb a spring it cannot, and the errors grow."""
    xs = [_sweep(0.5 * k) for k in range(3)]
    trials = [(x, 0.3 * x + simulate(x, FIG57, 0.0)) for x in xs]
    asked: list[list[int]] = []

    def factory(indices: list[int], slope: float = 0.3) -> FixedBackbone:
        asked.append(list(indices))
        return FixedBackbone(torque_nm=lambda a: slope * a)

    errors = cross_validate(trials, starts=0, backbone_factory=factory)
    assert asked == [[1, 2], [0, 2], [0, 1]]
    assert max(errors) < 0.01
    wrong = cross_validate(trials, starts=0, backbone_factory=lambda i: factory(i, 0.2))
    assert min(wrong) > 0.5


def test_a_polynomial_backbone_is_fitted_on_the_other_trials_only() -> None:
    """Trials 0 and 1 have a 0.3 N*m/deg spring, trial 2 a 0.5 N*m/deg one, all with Figure 57's
    hysteresis.  Held out, trial 2 is predicted as g + z by the fit of trials 0 and 1 alone (backbone and
    Bouc-Wen state), started from trial 2's own first torque: its error is that model's error, which the
    missing 0.2 N*m/deg makes large."""
    xs = [_sweep(0.5 * k) for k in range(3)]
    slopes = (0.3, 0.3, 0.5)
    trials = [(x, s * x + simulate(x, FIG57, 0.0)) for x, s in zip(xs, slopes, strict=True)]
    errors = cross_validate(trials, starts=0, backbone_degree=1)
    others = fit_trials(trials[:2], starts=0, backbone_degree=1)
    assert others.backbone is not None
    x, y = trials[2]
    g = others.backbone(x)
    predicted = g + simulate(x, others.params, float(y[0] - g[0]))
    expected = math.sqrt(float(np.mean((predicted - y) ** 2)))
    assert expected > 3.0  # about 0.2 N*m/deg of a +-60 deg sweep
    assert errors[2] == pytest.approx(expected, rel=1e-2)
