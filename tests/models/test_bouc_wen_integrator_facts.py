"""Facts of the refined integration of Eq 20-22 (models/bouc_wen/integrator.py, through the scheme
selector models/bouc_wen/schemes.py): on a piece where every sign is fixed and n = 1 the state equation
``dz/dx = A - z Psi`` has the closed form ``z = A/Psi + (z0 - A/Psi) exp(-Psi (x - x0))``, which the scheme
must follow (also across x = 0 inside one sample interval, and through a stiff transient), with the exact
derivatives of what it computes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.schemes import (
    EQ23,
    REFINED,
    BoucWenShape,
    Integration,
    Sensitivity,
    check_scheme,
    run_scheme,
    run_trial,
    run_trials,
    segment_starts,
)
from protocol_runner.models.bouc_wen.simulation import simulate
from tests.models.sensitivity import simulate_sensitivity

Arr = np.ndarray


def _torque(
    scheme: str, x: Arr, seg: Arr, z0: Arr, a: float, n: float, beta: Arr, bound: float, freeze: bool, z: Arr
) -> int:
    """run_scheme with the parameter records spelt out: the torque into ``z``, the first diverged index."""
    return run_scheme(x, seg, z0, BoucWenShape(a, n, beta), Integration(scheme, bound, freeze), z)


def _sensitivities(
    scheme: str,
    x: Arr,
    seg: Arr,
    z0: Arr,
    a: float,
    n: float,
    beta: Arr,
    bound: float,
    freeze: bool,
    z: Arr,
    dz: Arr,
    T: Arr,
    rows: Arr | None = None,
) -> int:
    """As :func:`_torque`, with ``dz/dtheta @ T`` at ``rows`` (every sample when None) into ``dz``."""
    shape, integration = BoucWenShape(a, n, beta), Integration(scheme, bound, freeze)
    return run_scheme(x, seg, z0, shape, integration, z, Sensitivity(dz, T, rows))


# the six sign terms of Eq 22 are all +1 where x > 0, dx > 0 and z > 0: Psi = sum(beta) = 1 per deg there
BETA = (0.3, 0.2, 0.1, 0.15, 0.15, 0.1)
PSI_POS = sum(BETA)
# where x < 0, dx > 0, z > 0: sgn(dx z) = 1, sgn(dx x) = -1, sgn(x z) = -1, sgn dx = 1, sgn z = 1, sgn x = -1
PSI_NEG = BETA[0] - BETA[1] - BETA[2] + BETA[3] + BETA[4] - BETA[5]
A = 2.0
LINEAR = BoucWenParams(A=A, n=1.0, beta=BETA)
FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))


def psi(sd: float, sx: float, sz: float) -> float:
    """Eq 22's shape function for the signs of dx, x and z."""
    b = BETA
    return b[0] * sd * sz + b[1] * sd * sx + b[2] * sx * sz + b[3] * sd + b[4] * sz + b[5] * sx


def relax(z0: float, a: float, psi: float, travel_deg: np.ndarray | float) -> np.ndarray:
    """Closed form of dz/dx = a - psi z (n = 1, fixed signs) after `travel_deg`."""
    return np.asarray(a / psi + (z0 - a / psi) * np.exp(-psi * np.asarray(travel_deg)))


def test_with_zero_betas_the_torque_rises_by_a_times_the_angle_on_any_path() -> None:
    """Psi = 0: dz/dx = A exactly, so z = z0 + A (x - x0) whatever the path (reversals, zero crossings)."""
    x = np.array([0.0, 3.0, -7.5, -2.0, 12.0, 12.0, 4.25])
    z = simulate(x, BoucWenParams(A=0.7, n=1.3, beta=(0.0,) * 6), 1.5)
    np.testing.assert_allclose(z, 1.5 + 0.7 * x, rtol=0.0, atol=1e-12)


def test_on_a_piece_of_fixed_signs_the_torque_is_the_closed_form_relaxation() -> None:
    x = np.linspace(0.5, 8.5, 9)
    z = simulate(x, LINEAR, 0.5)
    np.testing.assert_allclose(z, relax(0.5, A, PSI_POS, x - x[0]), rtol=0.0, atol=2e-3)
    # the same within 2e-3 when the samples are 0.05 deg apart: the result does not depend on the sampling
    fine = np.linspace(0.5, 8.5, 161)
    np.testing.assert_allclose(simulate(fine, LINEAR, 0.5)[::20], z, rtol=0.0, atol=2e-3)


def test_a_sample_interval_crossing_zero_is_cut_at_zero() -> None:
    """One interval from -4 to +6 deg: Psi changes at x = 0 (sgn x flips), so the state relaxes towards
    A/Psi_neg for 4 deg, then towards A/Psi_pos for 6 deg; Eq 23's single Euler step does not."""
    x = np.array([-4.0, 6.0])
    at_zero = relax(0.5, A, PSI_NEG, 4.0)
    expected = float(relax(float(at_zero), A, PSI_POS, 6.0))
    assert simulate(x, LINEAR, 0.5)[-1] == pytest.approx(expected, abs=2e-3)
    assert simulate(x, LINEAR, 0.5, scheme=EQ23)[-1] == pytest.approx(0.5 + 10.0 * (A - 0.5 * PSI_NEG))
    # the same interval the other way, from +6 down to -4 deg, with a negative torque that stays negative:
    # in the travel s = |dx| the state obeys dz/ds = sd (A - |z| Psi) = sd A - sd sz Psi z
    sd, sz = -1.0, -1.0
    mid = relax(-3.0, sd * A, sd * sz * psi(sd, 1.0, sz), 6.0)
    end = float(relax(float(mid), sd * A, sd * sz * psi(sd, -1.0, sz), 4.0))
    down = simulate(np.array([6.0, -4.0]), LINEAR, -3.0)[-1]
    assert end < -3.0 and down == pytest.approx(end, abs=2e-3)


def test_a_stiff_transient_inside_the_sample_intervals_is_followed_stably() -> None:
    """Psi = 50 per deg (the state saturates within a few hundredths of a degree): the default substep
    (0.1 deg, Psi h = 5) alone would make Heun's method unstable; the stiffness bound keeps each substep
    inside its stability region, so the torque relaxes monotonically to A/Psi as the closed form does."""
    stiff = BoucWenParams(A=50 * A, n=1.0, beta=tuple(50 * b for b in BETA))
    x = 0.5 + 0.02 * np.arange(20)
    z = simulate(x, stiff, 0.5)
    exact = relax(0.5, 50 * A, 50 * PSI_POS, x - x[0])
    assert np.all(np.diff(z) >= 0.0) and np.all(z <= 2.0 + 1e-12)
    np.testing.assert_allclose(z, exact, rtol=0.0, atol=0.02 * (2.0 - 0.5))
    coarse = np.array([0.5, 5.5, 10.5])  # 5 deg intervals: many substeps each, still on the closed form
    np.testing.assert_allclose(simulate(coarse, stiff, 0.5), [0.5, 2.0, 2.0], rtol=0.0, atol=1e-9)


def test_the_sensitivities_of_the_closed_form_are_reproduced() -> None:
    """d z/dA = (1 - e^{-Psi s}) / Psi and, every sign being +1 here, d z/d beta_k = d z/d Psi for all six
    = -A/Psi^2 (1 - e^{-Psi s}) - (z0 - A/Psi) s e^{-Psi s}."""
    x = np.linspace(0.5, 6.5, 7)
    s = x - x[0]
    z0, psi = 0.5, PSI_POS
    z, dz = simulate_sensitivity(x, LINEAR, z0)
    e = np.exp(-psi * s)
    np.testing.assert_allclose(dz[:, 0], (1.0 - e) / psi, rtol=0.0, atol=3e-3)
    d_psi = -A / psi**2 * (1.0 - e) - (z0 - A / psi) * s * e
    for k in range(6):
        np.testing.assert_allclose(dz[:, 2 + k], d_psi, rtol=0.0, atol=3e-3)
    np.testing.assert_array_equal(z, simulate(x, LINEAR, z0))


@pytest.mark.parametrize("z0", [0.0, 3.0])
@pytest.mark.parametrize("scheme", [REFINED, EQ23])
def test_the_sensitivities_are_the_derivatives_of_the_computed_torque(z0: float, scheme: str) -> None:
    """Against central differences of simulate on a loop with reversals and zero crossings at a coarse
    sampling (several substeps and cuts per interval), every parameter including n."""
    t = np.linspace(0.0, 1.3, 40)
    x = 40.0 * np.sin(2.0 * np.pi * t) + 5.0
    theta = FIG57.as_array()
    _, dz = simulate_sensitivity(x, FIG57, z0, scheme=scheme)
    for k in range(8):
        h = 1e-6 * max(abs(theta[k]), 1e-2)
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        fd = (
            simulate(x, BoucWenParams.from_array(up), z0, scheme=scheme)
            - simulate(x, BoucWenParams.from_array(down), z0, scheme=scheme)
        ) / (2.0 * h)
        scale = max(1e-3, float(np.max(np.abs(fd))))
        np.testing.assert_allclose(dz[:, k], fd, rtol=0.0, atol=1e-4 * scale, err_msg=str(k))


def test_each_segment_starts_afresh_and_the_asked_rows_are_those_of_the_full_jacobian() -> None:
    """Two trials in one pass: each restarts at its own z0 with zero sensitivities, exactly as if run
    alone; asking for some rows (a segment start among them) gives exactly those rows."""
    x1 = np.linspace(2.0, 30.0, 15)
    x2 = np.linspace(-5.0, -25.0, 11)
    x = np.concatenate([x1, x2])
    seg = np.array([0, x1.size, x.size], dtype=np.int64)
    z0 = np.array([0.5, -1.0])
    beta = np.array(LINEAR.beta)
    z = np.empty_like(x)
    full = np.empty((x.size, 8))
    T = np.eye(8)
    bad = _sensitivities(REFINED, x, seg, z0, A, 1.0, beta, 1e6, False, z, full, T)
    assert bad == -1
    np.testing.assert_array_equal(z[: x1.size], simulate(x1, LINEAR, 0.5))
    np.testing.assert_array_equal(z[x1.size :], simulate(x2, LINEAR, -1.0))
    np.testing.assert_array_equal(full[x1.size], np.zeros(8))
    np.testing.assert_array_equal(full[x1.size :], simulate_sensitivity(x2, LINEAR, -1.0)[1])
    for scheme in (REFINED, EQ23):
        every = np.empty((x.size, 8))
        zz = np.empty_like(x)
        _sensitivities(scheme, x, seg, z0, A, 1.0, beta, 1e6, False, zz, every, T)
        # rows in both trials (a trial's first sample among them), and rows of the first trial only
        for rows in ([3, x1.size, x1.size + 4, x.size - 1], [2, 5]):
            asked = np.array(rows, dtype=np.int64)
            some = np.empty((asked.size, 8))
            _sensitivities(scheme, x, seg, z0, A, 1.0, beta, 1e6, False, zz, some, T, rows=asked)
            np.testing.assert_array_equal(some, every[asked])


@pytest.mark.parametrize("scheme", [REFINED, EQ23])
def test_a_diverging_state_is_reported_at_its_first_sample_and_held_or_dropped(scheme: str) -> None:
    """Figure 57's (x < 0, dx < 0, z > 0) pattern is unstable: from +5 N*m at -10 deg bending further the
    state runs away.  The index of the first sample beyond the bound is returned; from there the torque
    is held at +bound (freeze) or NaN, and so are its sensitivities (0 frozen, NaN otherwise).  A second
    trial after it is integrated normally."""
    x1 = -10.0 - np.linspace(0.0, 50.0, 26)
    x2 = np.linspace(1.0, 20.0, 10)
    x = np.concatenate([x1, x2])
    seg = np.array([0, x1.size, x.size], dtype=np.int64)
    z0 = np.array([5.0, 0.0])
    beta = np.array(FIG57.beta)
    bound = 100.0
    free = simulate(x1, FIG57, 5.0, bound_nm=bound, scheme=scheme)
    first = int(np.argmax(np.isnan(free)))
    assert first > 0 and np.all(np.abs(free[:first]) <= bound)
    for freeze in (True, False):
        z = np.empty_like(x)
        dz = np.empty((x.size, 8))
        bad = _sensitivities(scheme, x, seg, z0, FIG57.A, FIG57.n, beta, bound, freeze, z, dz, np.eye(8))
        z_only = np.empty_like(x)
        assert _torque(scheme, x, seg, z0, FIG57.A, FIG57.n, beta, bound, freeze, z_only) == first == bad
        np.testing.assert_array_equal(z_only, z)
        np.testing.assert_array_equal(z[:first], free[:first])
        if freeze:
            np.testing.assert_array_equal(z[first : x1.size], bound)
            np.testing.assert_array_equal(dz[first : x1.size], 0.0)
        else:
            assert np.all(np.isnan(z[first : x1.size])) and np.all(np.isnan(dz[first : x1.size]))
        np.testing.assert_array_equal(z[x1.size :], simulate(x2, FIG57, 0.0, scheme=scheme))


def test_a_negative_state_diverges_to_minus_the_bound() -> None:
    """Eq 20-22 are odd under (x, z) -> (-x, -z) when the betas of sgn dx, sgn z and sgn x change sign
    (those three terms flip, the products do not): the mirror of the diverging run above runs away to
    -bound, where it is held, and is the negative of the original until then."""
    x = 10.0 + np.linspace(0.0, 50.0, 26)
    free = simulate(-x, FIG57, 5.0, bound_nm=100.0)
    assert np.isnan(free[-1])
    z = np.empty_like(x)
    seg = np.array([0, x.size], dtype=np.int64)
    mirror_beta = np.array(FIG57.beta) * np.array([1.0, 1.0, 1.0, -1.0, -1.0, -1.0])
    bad = _torque(REFINED, x, seg, np.array([-5.0]), FIG57.A, FIG57.n, mirror_beta, 100.0, True, z)
    assert bad == int(np.argmax(np.isnan(free))) > 0
    np.testing.assert_array_equal(z[bad:], -100.0)
    np.testing.assert_allclose(z[:bad], -free[:bad], rtol=1e-12, atol=1e-12)


def test_the_substep_length_is_a_positive_finite_angle_defaulting_to_a_tenth_of_a_degree() -> None:
    assert check_scheme(REFINED, None) == 0.1
    assert check_scheme(EQ23, 0.5) == 0.5
    for bad in (0.0, -0.1, math.inf, math.nan):
        with pytest.raises(InvalidInput, match="max_step_deg must be a positive finite angle"):
            check_scheme(REFINED, bad)
    with pytest.raises(InvalidInput, match="scheme must be one of refined, eq23, got 'euler'"):
        check_scheme("euler", None)


def test_a_longer_substep_is_a_coarser_integration() -> None:
    """Heun's method is second order: the error of the closed-form relaxation grows about as h^2 with the
    substep h (0.1 deg by default, 0.3 deg: about 9 times the error)."""
    x = np.linspace(0.5, 8.5, 9)
    exact = relax(0.5, A, PSI_POS, x - x[0])
    err_default = np.max(np.abs(simulate(x, LINEAR, 0.5) - exact))
    err_coarse = np.max(np.abs(simulate(x, LINEAR, 0.5, max_step_deg=0.3) - exact))
    assert 5.0 < err_coarse / err_default < 12.0


def test_a_scheme_name_read_at_run_time_selects_its_scheme() -> None:
    """A name built at run time (as one read from a protocol file is: a new string object, not the
    module's constant) selects the same scheme as the constant, for the torque and the sensitivities."""
    x = np.array([-4.0, 6.0, 1.0])
    seg = np.array([0, x.size], dtype=np.int64)
    beta = np.array(BETA)
    for name in (EQ23, REFINED):
        read = "".join(list(name))
        assert read == name and read is not name
        z_const, z_read = np.empty_like(x), np.empty_like(x)
        _torque(name, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, z_const)
        _torque(read, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, z_read)
        np.testing.assert_array_equal(z_read, z_const)
        dz_const, dz_read = np.empty((x.size, 8)), np.empty((x.size, 8))
        _sensitivities(name, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, z_const, dz_const, np.eye(8))
        _sensitivities(read, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, z_read, dz_read, np.eye(8))
        np.testing.assert_array_equal(dz_read, dz_const)
    eq23, refined = np.empty_like(x), np.empty_like(x)
    _torque(EQ23, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, eq23)
    _torque(REFINED, x, seg, np.array([0.5]), A, 1.0, beta, 1e6, False, refined)
    assert abs(eq23[1] - refined[1]) > 1.0  # the two schemes differ on this path


@pytest.mark.parametrize("scheme", [REFINED, EQ23])
def test_a_joint_without_stiffness_holds_zero_torque_and_only_a_moves_it(scheme: str) -> None:
    """A = 0 and z = 0: dz/dx = 0 - |0|^n Psi = 0, so the torque stays exactly zero on any path; the only
    sensitivity is to A, d z/dA = x - x0 (|z|^n and its derivatives vanish at z = 0)."""
    still = BoucWenParams(A=0.0, n=1.2, beta=BETA)
    x = np.array([0.0, 1.0, -2.0, 3.0, 3.0, 0.5])
    z, dz = simulate_sensitivity(x, still, 0.0, scheme=scheme)
    np.testing.assert_array_equal(z, 0.0)
    np.testing.assert_array_equal(simulate(x, still, 0.0, scheme=scheme), 0.0)
    np.testing.assert_allclose(dz[:, 0], x - x[0], rtol=0.0, atol=1e-12)
    np.testing.assert_array_equal(dz[:, 1:], 0.0)


def test_a_state_running_away_before_the_angle_crosses_zero_is_held_with_its_own_sign() -> None:
    """Only beta6 (the sgn x term) set, n = 2: bending down from +5 deg with z = +10, Psi = +1 and
    dz/ds = z^2 - A runs away upward within a fraction of a degree, before x reaches 0 in the interval
    5 -> -5 deg.  The sample is held at +bound (the direction it diverged in): the rest of the interval,
    where Psi = -1 would drive a runaway state the other way, is not integrated."""
    beta = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    x = np.array([5.0, -5.0, -6.0])
    seg = np.array([0, x.size], dtype=np.int64)
    z = np.empty_like(x)
    assert _torque(REFINED, x, seg, np.array([10.0]), 0.1, 2.0, beta, 100.0, True, z) == 1
    np.testing.assert_array_equal(z, [10.0, 100.0, 100.0])
    dz = np.empty((x.size, 8))
    zs = np.empty_like(x)
    assert (
        _sensitivities(REFINED, x, seg, np.array([10.0]), 0.1, 2.0, beta, 100.0, True, zs, dz, np.eye(8)) == 1
    )
    np.testing.assert_array_equal(zs, z)


@pytest.mark.parametrize("scheme", [REFINED, EQ23])
def test_trials_integrated_together_are_each_integrated_alone(scheme: str) -> None:
    """Trials of 1, 200 and 337 samples concatenated: their segments start where the previous ones end
    (segment_starts: 0, 1, 201, 538), and each trial's torque, from its own start, is bit for bit the
    trial integrated alone; with no trial, nothing."""
    params = BoucWenParams(A=0.3, n=1.2, beta=(0.01, 0.1, -0.1, -0.05, 0.09, 0.0))
    xs = [np.array([5.0]), *(30.0 * np.sin(np.linspace(0.0, 3 * np.pi, n)) for n in (200, 337))]
    z0s = [1.5, 0.0, -2.0]
    integration = Integration(scheme, 1e6)
    assert segment_starts(xs).tolist() == [0, 1, 201, 538]
    together, bad = run_trials(xs, params, z0s, integration)
    assert bad == -1 and [t.size for t in together] == [1, 200, 337]
    for x, z0, torque in zip(xs, z0s, together, strict=True):
        alone, alone_bad = run_trial(x, params, z0, integration)
        assert alone_bad == -1
        np.testing.assert_array_equal(torque, alone)
    assert run_trials([], params, [], integration)[0] == []
