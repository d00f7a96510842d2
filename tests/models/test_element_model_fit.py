"""The element model's fit on synthetic loops made from known elements: the intervals cover the truth at
about their nominal rate, the brakes are fitted as their sum, an unidentifiable parameter is flagged, and a
prediction carries a declared factor change to another configuration."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.analysis.model_comparison import compare_models, motions_of
from protocol_runner.analysis.model_fit import fit_element_model
from protocol_runner.models.element_model import (
    Motion,
    Stacked,
    layout,
    model_torque_nm,
    stacked_torque_nm,
    torque_jacobian,
    transfer,
    unit_dahl_friction,
)
from protocol_runner.models.elements import build_device

TRUTH = {
    ("torsion", "stiffness_nm_per_deg"): 0.1,
    ("torsion", "neutral_deg"): 60.0,
    ("brake", "torque_nm"): 0.5,
    ("brake", "transition_deg"): 2.0,
    ("damper", "damping_nm_s_per_deg"): 0.02,
}


def _device(damping: float = 0.02, stiffness: float = 0.1, brakes: tuple[float, ...] = (0.5,)):
    items = [
        ("torsion", "torsion_spring", {"stiffness_nm_per_deg": stiffness, "neutral_deg": 60.0}),
        ("damper", "viscous_damper", {"damping_nm_s_per_deg": damping}),
    ]
    names = ["brake", "hinge"]
    items += [
        (names[i], "coulomb_brake", {"torque_nm": t, "transition_deg": 2.0}) for i, t in enumerate(brakes)
    ]
    return build_device(items)


def _trials(device, rng: np.random.Generator, *, trials: int = 3, noise_nm: float = 0.1, rho: float = 0.9):
    """Sinusoids 20-110 deg at two speeds, 50 Hz, with AR(1) noise of lag-1 correlation `rho`."""
    lay = layout(device)
    out = []
    for i in range(trials):
        period = 6.0 if i % 2 == 0 else 3.0
        t = np.arange(0.0, 2.0 * period, 0.02)
        angle = 65.0 - 45.0 * np.cos(2.0 * math.pi * t / period)
        m = Motion.from_samples(t, angle, np.zeros_like(t))
        torque = model_torque_nm(lay, lay.declared, m)
        e = rng.normal(0.0, noise_nm * math.sqrt(1 - rho * rho), t.size)
        noise = np.zeros_like(t)
        for j in range(1, t.size):
            noise[j] = rho * noise[j - 1] + e[j]
        out.append((t, angle, torque + noise))
    return out


def _motions(trials):
    return [Motion.from_samples(*tr) for tr in trials]


def test_intervals_cover_the_true_parameters_at_about_their_nominal_rate() -> None:
    device = _device()
    hits, total = 0, 0
    for seed in range(12):
        motions = _motions(_trials(device, np.random.default_rng(seed)))
        fit = fit_element_model(
            motions, layout(device, angle_deg=np.concatenate([m.angle_deg for m in motions]))
        )
        for e in fit.estimates:
            total += 1
            hits += e.ci95_low <= TRUTH[(e.element, e.parameter)] <= e.ci95_high
    # nominal 95 %; intervals three times too narrow would cover about half
    assert total == 60
    assert hits / total >= 0.8


def test_the_fit_recovers_the_damper_and_brake() -> None:
    device = _device()
    motions = _motions(_trials(device, np.random.default_rng(1), noise_nm=0.02))
    fit = fit_element_model(motions, layout(device))
    assert math.isclose(fit.values[("damper", "damping_nm_s_per_deg")], 0.02, rel_tol=0.1)
    assert math.isclose(fit.values[("brake", "torque_nm")], 0.5, rel_tol=0.1)
    assert all(e.identified for e in fit.estimates)


def test_the_damper_survives_the_angle_sensors_noise() -> None:
    """A 200 Hz loop whose angle carries white sensor noise of 0.035 deg (the elbow dry run's, after its
    50 Hz filter): a speed differenced over single samples would carry about 5 deg/s of noise, as much
    variance as the speed's variation within a stroke that tells the damper from the brake, and the fit
    would give the damper about 0.012 and the brake its torque. The comparison's motions difference the
    angle over the samples the fit keeps (about one degree apart) and recover both."""
    device = _device(stiffness=0.0)
    lay = layout(device)
    rng = np.random.default_rng(3)
    trials = []
    for _ in range(3):
        t = np.arange(0.0, 6 * 14.1, 0.005)
        angle = 65.0 - 45.0 * np.cos(2.0 * math.pi * t / 14.1)  # 20 deg/s peak
        torque = model_torque_nm(lay, lay.declared, Motion.from_samples(t, angle, np.zeros_like(t)))
        measured = angle + rng.normal(0.0, 0.035, t.size)
        trials.append((t, measured, torque + rng.normal(0.0, 0.25, t.size)))
    fit = fit_element_model(
        motions_of(trials), layout(device, angle_deg=np.concatenate([a for _, a, _ in trials]))
    )
    assert abs(fit.values[("damper", "damping_nm_s_per_deg")] - 0.02) < 0.1 * 0.02
    assert abs(fit.values[("brake", "torque_nm")] - 0.5) < 0.05


def test_brakes_acting_together_are_fitted_as_their_sum() -> None:
    device = _device(brakes=(0.4, 0.3))
    motions = _motions(_trials(device, np.random.default_rng(2), noise_nm=0.02))
    fit = fit_element_model(motions, layout(device))
    summed = [e for e in fit.estimates if e.parameter == "torque_nm"]
    assert [e.element for e in summed] == ["brake+hinge"]
    assert math.isclose(summed[0].value, 0.7, rel_tol=0.05)
    assert "sum of brake, hinge" in summed[0].note


def test_a_parameter_the_data_cannot_determine_is_flagged_unidentified() -> None:
    # a spring too weak to show: its neutral angle moves the torque by microns of N*m
    device = _device(stiffness=1e-5)
    motions = _motions(_trials(device, np.random.default_rng(3)))
    fit = fit_element_model(motions, layout(device))
    neutral = next(e for e in fit.estimates if e.parameter == "neutral_deg")
    assert not neutral.identified
    assert "unidentified" in neutral.text()
    brake = next(e for e in fit.estimates if e.parameter == "torque_nm")
    assert brake.identified


def test_a_declared_factor_change_scales_the_fitted_value() -> None:
    a, b = _device(damping=0.02), _device(damping=0.04)
    fitted = {**layout(a).declared, ("damper", "damping_nm_s_per_deg"): 0.018, ("brake", "torque_nm"): 0.55}
    carried = transfer(layout(a), layout(b), fitted)
    assert math.isclose(carried[("damper", "damping_nm_s_per_deg")], 0.036)
    assert carried[("brake", "torque_nm")] == 0.55  # declared equal: A's fitted value


def test_the_comparison_flags_a_model_whose_loop_energy_is_off() -> None:
    device = _device()
    trials = _trials(device, np.random.default_rng(4), noise_nm=0.02)
    cmp = compare_models(trials, device)
    rows = {r.model: r for r in cmp.rows}
    assert set(rows) == {"elements", "dahl"}
    assert not rows["elements"].energy_flag  # the true model
    assert rows["dahl"].energy_flag  # no damper: the reduced model misses its energy at two speeds
    assert rows["elements"].bic < rows["dahl"].bic
    assert rows["elements"].heldout_rmse_nm < rows["dahl"].heldout_rmse_nm


def test_the_model_jacobian_is_the_derivative_of_the_model_torque() -> None:
    """Every column of `torque_jacobian` (exact for the friction sum and the damper, a difference of one
    element's torque for an elastic parameter) matches a central difference of the whole model torque."""
    device = _device(brakes=(0.5, 0.2))
    lay = layout(device)
    stacked = Stacked.of(_motions(_trials(device, np.random.default_rng(3), trials=2)))
    values = dict(lay.declared)
    jac = torque_jacobian(lay, values, stacked, np.ones(len(lay.free)))
    for j, key in enumerate(lay.free):
        h = 1e-5 * max(1.0, abs(values[key]))
        up = stacked_torque_nm(lay, {**values, key: values[key] + h}, stacked)
        down = stacked_torque_nm(lay, {**values, key: values[key] - h}, stacked)
        numeric = (up - down) / (2.0 * h)
        scale = float(np.max(np.abs(numeric)))
        assert scale > 0.0, key
        assert float(np.max(np.abs(jac[:, j] - numeric))) < 1e-5 * scale + 1e-9, key


def test_a_declared_shift_of_an_angle_moves_the_fitted_angle_by_it() -> None:
    """The torsion spring's neutral angle declared 60 deg in A and 70 deg in B: A's fitted 61.5 deg is
    carried as 71.5 deg (a shift), while a changed stiffness scales (0.1 -> 0.2: A's fitted 0.11 -> 0.22)."""
    a = _device()
    b = build_device(
        [
            ("torsion", "torsion_spring", {"stiffness_nm_per_deg": 0.2, "neutral_deg": 70.0}),
            ("damper", "viscous_damper", {"damping_nm_s_per_deg": 0.02}),
            ("brake", "coulomb_brake", {"torque_nm": 0.5, "transition_deg": 2.0}),
        ]
    )
    fitted = {
        **layout(a).declared,
        ("torsion", "neutral_deg"): 61.5,
        ("torsion", "stiffness_nm_per_deg"): 0.11,
    }
    carried = transfer(layout(a), layout(b), fitted)
    assert carried[("torsion", "neutral_deg")] == pytest.approx(71.5, rel=1e-12)
    assert carried[("torsion", "stiffness_nm_per_deg")] == pytest.approx(0.22, rel=1e-12)


@pytest.mark.parametrize(("start", "sense"), [(1.0, 1.0), (-1.0, -1.0)])
def test_dahl_friction_starts_sliding_in_its_first_moves_sense(start: float, sense: float) -> None:
    """A trial that rests for three samples and then moves up (or down) holds the full level in that
    sense from its first sample: the friction of a motion starting from rest opposes it at once."""
    angle = np.array([10.0, 10.0, 10.0, 10.0 + start, 10.0 + 2 * start, 10.0 + 3 * start])
    speed = np.gradient(angle, 0.02)
    unit, _ = unit_dahl_friction(angle, speed, np.array([0, angle.size]), 2.0, 0.0, 1.0)
    assert unit[0] == sense and unit[1] == sense and unit[2] == sense
    assert np.all(np.sign(unit[3:]) == sense)


def test_a_trial_that_never_moves_has_no_dahl_friction() -> None:
    angle = np.full(5, 42.0)
    unit, _ = unit_dahl_friction(angle, np.zeros(5), np.array([0, 5]), 2.0, 0.0, 1.0)
    assert np.all(unit == 0.0)
