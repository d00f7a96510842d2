"""Facts of the Bouc-Wen fitter (thesis §6.2.3, Figure 56): concatenated trials are the same fit as the
trials given apart, decimation drops residuals but not the angle path of the refined scheme, the
quasi-random starts cover the bounds, one valley is polished once, and an Eq 23 fit on decimated samples
that does not carry over to every sample is redone there."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen import fitting as bw_fitting
from protocol_runner.models.bouc_wen.fitting import fit, fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.problem import Problem
from protocol_runner.models.bouc_wen.records import DEFAULT_BOUNDS
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
AT_TRUTH = {"starts": 0, "initial": FIG57, "data_starts": False}


def _loop(n: int, phase: float = 0.0, z0: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    x = 60.0 * np.sin(2 * np.pi * np.arange(n) / 160.0 + phase)
    return x, simulate(x, FIG57, z0=z0)


def test_concatenated_trials_are_fitted_as_the_separate_trials() -> None:
    """fit(x, y, trials=...) cuts the samples into the trials (each restarting the recursion at its own
    first torque), the same fit as fit_trials of the pieces; 600 samples in all."""
    (x1, y1), (x2, y2) = _loop(300), _loop(300, 1.0, z0=2.0)
    joined = fit(np.concatenate([x1, x2]), np.concatenate([y1, y2]), trials=[300, 300], **AT_TRUTH)
    apart = fit_trials([(x1, y1), (x2, y2)], **AT_TRUTH)
    assert joined.n_samples == 600 and len(joined.trial_rmse_nm) == 2
    assert joined.rmse_nm < 1e-8
    np.testing.assert_allclose(joined.params.as_array(), apart.params.as_array(), rtol=1e-12)
    np.testing.assert_allclose(joined.params.as_array(), FIG57.as_array(), rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize(("n_angle", "n_torque"), [(10, 12), (12, 10)])
def test_angle_and_torque_of_unequal_length_are_refused(n_angle: int, n_torque: int) -> None:
    x, y = _loop(20)
    with pytest.raises(InvalidInput, match=f"{n_angle} angle samples but {n_torque} torque samples"):
        fit(x[:n_angle], y[:n_torque])


def test_a_static_joint_and_a_joint_without_torque_are_refused() -> None:
    x, y = _loop(50)
    with pytest.raises(InvalidInput, match="angle never changes"):
        fit_trials([(np.full(50, 10.0), y)])
    with pytest.raises(InvalidInput, match="torque is zero everywhere"):
        fit_trials([(x, np.zeros(50)), (x, np.zeros(50))])


def test_decimation_drops_residuals_but_the_refined_scheme_follows_every_sample() -> None:
    """Refined-scheme data, decimated by 4 for the fit: the model still integrates along every sample's
    angle, so the true parameters reproduce every sample and the fit started there keeps them (an
    integration along the kept samples only would cut the corners of the sine and move away)."""
    x, y = _loop(1200)
    result = fit_trials([(x, y)], max_samples_per_trial=300, **AT_TRUTH)
    assert result.stride == (4,)
    assert result.rmse_nm < 1e-8
    np.testing.assert_allclose(result.params.as_array(), FIG57.as_array(), rtol=1e-6, atol=1e-9)


def test_a_long_trial_is_fitted_through_the_mid_size_copy() -> None:
    """3200 samples (more than the 1500 of the mid-size copy on which the polish starts): the fit from the
    truth ends at it on every sample."""
    x, y = _loop(3200)
    result = fit_trials([(x, y)], **AT_TRUTH)
    assert result.stride == (1,)
    assert result.r2 > 0.99999
    np.testing.assert_allclose(result.params.as_array(), FIG57.as_array(), rtol=1e-3, atol=1e-5)


def _starts_solved(monkeypatch: pytest.MonkeyPatch) -> list[np.ndarray]:
    """The start of every solve the fit makes, in order."""
    seen: list[np.ndarray] = []
    solve = Problem.solve

    def recording_solve(self: Problem, u0: np.ndarray, *args: object, **kwargs: object) -> object:
        seen.append(np.array(u0))
        return solve(self, u0, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(Problem, "solve", recording_solve)
    return seen


def test_the_quasi_random_starts_are_spread_over_the_bounds(monkeypatch: pytest.MonkeyPatch) -> None:
    """Every quasi-random start lies inside the box of the dimensionless parameters, and no two share a
    coordinate (a Halton sequence mapped onto the box, not a corner of it)."""
    seen = _starts_solved(monkeypatch)
    fit_trials([_loop(240)], starts=6, data_starts=False)
    starts = np.array(seen[:6])
    lower, upper = DEFAULT_BOUNDS.lower(), DEFAULT_BOUNDS.upper()
    assert np.all(starts >= lower) and np.all(starts <= upper)
    for k in range(8):
        assert np.unique(starts[:, k]).size == 6, k


def test_one_valley_is_polished_once_and_polish_zero_still_polishes_the_best() -> None:
    """Of the short solves only distinct ones (not within 0.1 % of a chosen cost) close to the best (within
    5 %) are polished, and at least one is, whatever ``polish`` says."""
    rng = np.random.default_rng(5)
    x, y = _loop(240)
    noisy = y + rng.normal(0.0, 0.3, y.size)
    twice = fit_trials([(x, noisy)], starts=0, initial=[FIG57, FIG57], data_starts=False, polish=4)
    assert len(twice.polished_rmse_nm) == 1  # the same start twice: the same short-solve cost
    # a start whose short solve ends far above the best (more than 5 % in cost) is not polished either
    far = BoucWenParams(A=0.02, n=2.5, beta=(0.0,) * 6)
    apart = fit_trials([(x, noisy)], starts=0, initial=[FIG57, far], data_starts=False, polish=4)
    best, other = apart.start_rmse_nm
    assert other**2 > 1.05 * best**2
    assert len(apart.polished_rmse_nm) == 1
    none = fit_trials([(x, noisy)], starts=0, initial=FIG57, data_starts=False, polish=0)
    assert len(none.polished_rmse_nm) == 1
    assert none.rmse_nm == pytest.approx(twice.rmse_nm, rel=1e-9)


def _rom_loop() -> tuple[np.ndarray, np.ndarray]:
    data = np.load(Path(__file__).resolve().parent / "data" / "brace_rom_stop_loop.npz")
    return data["angle_deg"].astype(np.float64), data["torque_nm"].astype(np.float64)


def test_an_eq23_fit_that_does_not_carry_over_from_decimated_samples_is_redone_on_every_sample(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A loop with range-of-motion stops (nearly vertical branches): fitted by Eq 23 on every second sample,
    its recursion does not hold on every sample; fit_trials then refits on every sample and returns that
    better fit (the early switch inside the fit is turned off here, so the decimated fit happens)."""
    monkeypatch.setattr(bw_fitting, "_diverges_when_decimated", lambda *args: False)
    x, y = _rom_loop()
    result = fit_trials([(x, y)], starts=8, scheme="eq23")
    assert result.stride == (1,) and result.n_samples_fitted == x.size
    assert not result.diverged and result.r2 > 0.9


def test_an_eq23_fit_that_carries_over_from_decimated_samples_keeps_its_stride() -> None:
    """Eq 23 data of a smooth loop fitted by Eq 23 on every second sample: the fit describes every sample
    well (R^2 near 1), so it is not redone there."""
    x = 60.0 * np.sin(2 * np.pi * np.arange(1200) / 600.0)
    y = simulate(x, FIG57, z0=0.0, scheme="eq23")
    result = fit_trials([(x, y)], max_samples_per_trial=600, scheme="eq23", **AT_TRUTH)
    assert result.stride == (2,)
    assert result.r2 > 0.99


def test_a_loop_whose_decimated_recursion_diverges_is_polished_on_every_sample_at_once(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The same loop with the early switch on: the best start is stable on the coarse screening copy but
    its Eq 23 recursion diverges on every second sample, so the fit polishes on every sample from the
    start - one fit, no decimated fit to redo."""
    calls: list[tuple[int, ...]] = []
    inner = bw_fitting._fit_segments

    def counting(*args: object) -> object:
        result = inner(*args)  # type: ignore[arg-type]
        calls.append(result.stride)
        return result

    monkeypatch.setattr(bw_fitting, "_fit_segments", counting)
    x, y = _rom_loop()
    result = fit_trials([(x, y)], starts=8, scheme="eq23")
    assert calls == [(1,)]
    assert result.n_samples_fitted == x.size and not result.diverged


def test_the_best_polished_start_is_the_one_returned(monkeypatch: pytest.MonkeyPatch) -> None:
    """Two starts a little apart (their costs within 5 %, not the same valley), each polished by a single
    step: the fit returns the lower polished cost, whichever order they were polished in."""
    monkeypatch.setattr(bw_fitting, "_SHORT_NFEV", 1)
    monkeypatch.setattr(bw_fitting, "_POLISH_NFEV", 1)
    rng = np.random.default_rng(5)
    x, y = _loop(240)
    noisy = y + rng.normal(0.0, 0.3, y.size)
    nearby = BoucWenParams(A=FIG57.A * 1.005, n=FIG57.n, beta=FIG57.beta)
    result = fit_trials([(x, noisy)], starts=0, initial=[nearby, FIG57], data_starts=False, polish=2)
    assert len(result.polished_rmse_nm) == 2
    assert result.polished_rmse_nm[0] != result.polished_rmse_nm[1]
    assert result.rmse_nm == pytest.approx(min(result.polished_rmse_nm), rel=1e-12)


@pytest.mark.parametrize(("n_angle", "n_torque"), [(10, 12), (12, 10)])
def test_a_trial_with_angle_and_torque_of_unequal_length_is_refused(n_angle: int, n_torque: int) -> None:
    x, y = _loop(20)
    with pytest.raises(InvalidInput, match=f"trial 1: {n_angle} angle samples but {n_torque} torque samples"):
        fit_trials([(x, y), (x[:n_angle], y[:n_torque])])


def test_the_finer_check_of_a_fit_at_the_truth_stays_near_the_data() -> None:
    """rmse_refined_nm integrates the fitted model 4x finer (its divergence bound 10x the torque scale): at
    the true parameters of refined-scheme data it is a small fraction of the torque, not the torque."""
    x, y = _loop(640)
    result = fit_trials([(x, y)], **AT_TRUTH)
    torque_rms = float(np.sqrt(np.mean(y**2)))
    assert torque_rms > 1.0
    assert result.rmse_refined_nm < 0.05 * torque_rms


def _problems_built(monkeypatch: pytest.MonkeyPatch) -> list[tuple[int, str, float | None]]:
    """(samples, scheme, substep) of every Problem the fit builds."""
    built: list[tuple[int, str, float | None]] = []
    init = Problem.__init__

    def recording_init(self: Problem, samples, bounds, scale, scheme="refined", max_step_deg=None) -> None:  # type: ignore[no-untyped-def]
        built.append((int(samples.x.size), str(scheme), max_step_deg))
        init(self, samples, bounds, scale, scheme, max_step_deg)

    monkeypatch.setattr(Problem, "__init__", recording_init)
    return built


def test_the_refined_fit_screens_at_half_a_degree_then_polishes_a_mid_copy_at_a_quarter(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The refined scheme's stages (docs/analysis.md): every sample's path at the default substep, the
    starts screened on a 400-sample copy at 0.5 deg, polished on a 1,500-sample copy at 0.25 deg - also
    for a scheme name made at run time (read from a file), not only the literal."""
    built = _problems_built(monkeypatch)
    x, y = _loop(3200)
    scheme = "".join(["re", "fined"])
    fit_trials([(x, y)], scheme=scheme, **AT_TRUTH)
    steps = {step for _, _, step in built}
    assert (3200, "refined", None) in built
    assert any(n <= 400 and step == bw_fitting.SCREEN_STEP_DEG for n, _, step in built)
    assert any(400 < n < 3200 and step == bw_fitting.MID_STEP_DEG for n, _, step in built)
    assert steps <= {None, bw_fitting.SCREEN_STEP_DEG, bw_fitting.MID_STEP_DEG}


def test_no_mid_copy_when_the_fitted_samples_are_already_fewer(monkeypatch: pytest.MonkeyPatch) -> None:
    """With at most 1,000 compared samples per trial (stride 4) the 1,500-sample copy (stride 3) would be
    finer than what is fitted: no polish on it."""
    built = _problems_built(monkeypatch)
    x, y = _loop(3200)
    fit_trials([(x, y)], max_samples_per_trial=1000, **AT_TRUTH)
    assert all(step != bw_fitting.MID_STEP_DEG for _, _, step in built)


def test_one_quasi_random_start_is_one_start_and_the_seed_scrambles_them(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    x, y = _loop(240)
    one = fit_trials([(x, y)], starts=1, data_starts=False)
    assert one.n_starts == 1
    seen = _starts_solved(monkeypatch)
    fit_trials([(x, y)], starts=2, data_starts=False, seed=1)
    first = np.array(seen[:2])
    seen.clear()
    fit_trials([(x, y)], starts=2, data_starts=False, seed=2)
    assert not np.allclose(first, np.array(seen[:2]))  # a Halton sequence unscrambled ignores the seed


def test_a_refined_fit_is_never_redone_on_every_sample(monkeypatch: pytest.MonkeyPatch) -> None:
    """The refit on every sample is the Eq 23 scheme's guard (its explicit steps depend on the sampling);
    the refined integration follows every sample already, so a poor refined fit is not fitted twice."""
    calls: list[object] = []
    inner = bw_fitting._fit_segments

    def counting(*args: object, **kwargs: object) -> object:
        calls.append(args)
        return inner(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(bw_fitting, "_fit_segments", counting)
    x, y = _loop(240)
    noise = np.random.default_rng(3).normal(0.0, 3.0 * float(np.std(y)), y.size)
    poor = fit_trials([(x, y + noise)], max_samples_per_trial=80, **AT_TRUTH)
    assert poor.stride == (3,) and poor.r2 < bw_fitting.FULL_REFIT_R2
    assert len(calls) == 1
