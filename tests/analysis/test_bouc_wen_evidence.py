"""The evidence stored with every Bouc-Wen fit: held-out trials that never enter their own fit,
parameter intervals and the weak-identification mark, and the model's loop energy beside the data's."""

from __future__ import annotations

import h5py
import numpy as np
import pytest

from protocol_runner.analysis.bouc_wen_fit import fit_configuration, loop_energy, model_torques
from protocol_runner.analysis.service import bouc_wen_result
from protocol_runner.archive.results import bouc_wen_fill
from protocol_runner.models.bouc_wen.fitting import fit_trials
from protocol_runner.models.bouc_wen.identifiability import identify
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
# saturates on loading in every phase (psi = 0.08 at positive angles, 0.02 at negative ones): stable from
# any state, unlike Figure 57's (+, +, -) pattern
STABLE = BoucWenParams(A=0.3, n=1.2, beta=(0.05, 0.0, 0.0, 0.0, 0.0, 0.03))
PERIOD_S = 8.17


def sinusoid(periods: float, rate_hz: float, phase: float = 0.0) -> np.ndarray:
    t = np.arange(0.0, periods * PERIOD_S, 1.0 / rate_hz)
    return 60.0 * np.sin(2.0 * np.pi * t / PERIOD_S + phase)


def noisy(x: np.ndarray, params: BoucWenParams, seed: int, noise_nm: float = 0.1) -> np.ndarray:
    return simulate(x, params, 0.0) + noise_nm * np.random.default_rng(seed).standard_normal(x.size)


def test_a_held_out_trial_that_differs_from_the_others_raises_its_held_out_error() -> None:
    """Trials 1-2 from one joint, trial 3 from a stiffer one (A 50 % higher): fitted on all three, the
    model compromises; left out, trial 3 is predicted from the other two only, and its error rises.
    (Thesis-form data and model, torque = z.)"""
    x = sinusoid(2, 25.0)
    stiffer = BoucWenParams(A=0.45, n=STABLE.n, beta=STABLE.beta)
    segments = [(x, noisy(x, STABLE, 0)), (x, noisy(x, STABLE, 1)), (x, noisy(x, stiffer, 2))]
    result, cv = fit_configuration(segments, starts=4, backbone_degree=None)
    assert len(cv) == 3
    assert cv[2] > 1.3 * result.trial_rmse_nm[2]
    assert cv[2] > 1.5 * max(cv[0], cv[1])


def test_a_held_out_trial_never_enters_its_own_fit(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every held-out fit sees only the other trials' samples and starts from points computed from them:
    no warm start from the fit on all trials (which was fitted on the held-out trial too)."""
    from protocol_runner.models.bouc_wen import fitting

    seen: list[tuple[list[int], object]] = []
    real = fitting.fitted_params

    def spy(segments, options):  # type: ignore[no-untyped-def]
        seen.append(([round(float(y[1]) * 1e6) for _, y in segments], options.initial))
        return real(segments, options)

    monkeypatch.setattr(fitting, "fitted_params", spy)
    xs = [sinusoid(2, 25.0, phase) for phase in (0.0, 0.3, 0.6)]
    segments = [(x, noisy(x, STABLE, k)) for k, x in enumerate(xs)]
    marks = [round(float(y[1]) * 1e6) for _, y in segments]
    fit_configuration(segments, starts=2)
    assert len(seen) == 3
    for k, (fitted, initial) in enumerate(seen):
        assert marks[k] not in fitted and len(fitted) == 2
        assert initial is None


def test_a_known_parameter_set_lies_within_its_intervals_at_two_sampling_rates() -> None:
    for rate_hz in (25.0, 200.0):
        segments = [(x, noisy(x, FIG57, k)) for k, x in enumerate([sinusoid(2, rate_hz)] * 2)]
        result = identify(segments, fit_trials(segments))
        theta = FIG57.as_array()
        assert np.all(np.array(result.param_interval_low) <= theta), rate_hz
        assert np.all(theta <= np.array(result.param_interval_high)), rate_hz
        lo, hi = result.n_interval
        assert lo < FIG57.n < hi and lo > 0.5 and hi < 3.0
        assert not result.weakly_identified, result.weak_reasons


@pytest.mark.parametrize("backbone_degree", [None, 9])
def test_zero_loss_data_give_a_model_without_loop_energy_and_weakly_identified(
    backbone_degree: int | None,
) -> None:
    """A lossless elastic joint (torque proportional to the angle): the fitted model's loop encloses no
    energy, and since there is no hysteresis to describe, the fit is marked weakly identified."""
    segments = []
    for k in range(2):
        x = sinusoid(3.25, 25.0)
        segments.append((x, 0.3 * x + 0.05 * np.random.default_rng(k).standard_normal(x.size)))
    result, _ = fit_configuration(
        segments, starts=4, cross_validate_trials=False, backbone_degree=backbone_degree
    )
    energy = loop_energy(segments, model_torques(segments, result))
    assert abs(energy.data_j) < 0.05 and abs(energy.model_j) < 0.05
    assert result.weakly_identified and result.weak_reasons


def test_model_loop_energy_agrees_with_the_data_where_they_lose_energy() -> None:
    segments = [(x, noisy(x, FIG57, k)) for k, x in enumerate([sinusoid(3.25, 50.0)] * 2)]
    result, _ = fit_configuration(segments, starts=4, cross_validate_trials=False, backbone_degree=None)
    energy = loop_energy(segments, model_torques(segments, result))
    assert energy.data_j > 1.0
    assert energy.model_j == pytest.approx(energy.data_j, rel=0.2)
    assert energy.model_dissipates


def test_the_archive_gets_the_evidence_with_the_fit(tmp_path) -> None:  # type: ignore[no-untyped-def]
    segments = [(x, noisy(x, FIG57, k)) for k, x in enumerate([sinusoid(3.25, 25.0)] * 2)]
    result, cv = fit_configuration(segments, starts=2, backbone_degree=None)
    with h5py.File(tmp_path / "a.h5", "w") as f:
        bouc_wen_fill("config_01", bouc_wen_result(result, segments, cv))(f)
        a = f["configurations/config_01/fits/bouc_wen"].attrs
        assert a["scheme"] == "refined"
        assert abs(a["rmse_refined_nm"] - a["rmse_nm"]) <= 0.02 * a["rmse_nm"]
        assert len(a["cv_rmse_nm"]) == 2
        assert a["optimizer_status"] > 0 and len(a["start_rmse_nm"]) == a["n_starts"]
        assert len(a["param_interval_low"]) == 8 and len(a["n_interval"]) == 2
        assert not a["weakly_identified"] and a["weak_reasons"] == ""
        assert a["model_energy_j"] == pytest.approx(a["data_energy_j"], rel=0.2)
        assert a["model_dissipates"]
        assert a["backbone"] == "none" and len(a["backbone_coef"]) == 0


def test_backbone_separates_the_stops_from_the_hysteresis(tmp_path) -> None:  # type: ignore[no-untyped-def]
    """Configuration 1's dry-run loop, whose range-of-motion stops make both ends nearly vertical (elastic
    torque, no loss): torque = g(angle) + z follows it far better than the thesis form torque = z, its loop
    energy is within 20 % of the data's, and the archive stores g with a model torque that includes it."""
    from pathlib import Path

    data = np.load(Path(__file__).parents[1] / "models" / "data" / "brace_rom_stop_loop.npz")
    segments = [(data["angle_deg"].astype(np.float64), data["torque_nm"].astype(np.float64))]
    with_backbone, _ = fit_configuration(segments, starts=4, cross_validate_trials=False)
    thesis, _ = fit_configuration(segments, starts=4, cross_validate_trials=False, backbone_degree=None)
    assert with_backbone.backbone is not None and thesis.backbone is None
    assert with_backbone.rmse_nm < 0.5 * thesis.rmse_nm
    energy = loop_energy(segments, model_torques(segments, with_backbone))
    assert energy.data_j > 1.0
    assert energy.model_j == pytest.approx(energy.data_j, rel=0.2)
    with h5py.File(tmp_path / "b.h5", "w") as f:
        bouc_wen_fill("config_01", bouc_wen_result(with_backbone, segments, []))(f)
        g = f["configurations/config_01/fits/bouc_wen"]
        assert g.attrs["backbone"] == "polynomial" and len(g.attrs["backbone_coef"]) == 10
        model = g["model_torque_nm"][:]
        measured = g["torque_nm"][:]
        assert np.sqrt(np.mean((model - measured) ** 2)) < 1.5 * with_backbone.rmse_nm
