"""Benchmark: generalised Bouc-Wen fit of one configuration (thesis §6.2).

Data: one configuration's worth - three 65 s trials at 1 kHz of a 0-130 deg sinusoid (period 8.17 s, the
thesis's full-speed trajectory), each centred on its mean angle (note under Table 4), torque from the
Eq 23 recursion with the Figure 57 parameters plus seeded Gaussian noise.

Compared, on exactly the same samples:

* ours: ``fit_trials`` (analytic Jacobian, bounds, multi-start), default settings;
* the plain baseline: the same numba Eq 23 recursion (each trial restarted at its own first torque,
  the same finite penalty for divergence) + ``scipy.optimize.least_squares`` with its default
  finite-difference Jacobian and default options, starting from A = n = 1, betas = 0 (Figure 56's A and
  n), no bounds.  It sees the decimated samples ``fit_trials`` fits (every ``stride``-th sample of
  each trial).

In the same run, the thesis's Eq 23 recursion (``fit_trials(scheme="eq23")``) against the fit the
pipeline makes for a configuration: step-independent integration, multi-start, the 4x-finer check, n's
profile interval and the other parameter intervals, the backbone
(``analysis.bouc_wen_fit.fit_configuration`` without cross-validation, which is one such fit per held-out
trial).

Both RMSEs are computed on every 1 kHz sample, and both timings include that computation (``fit_trials``
returns it, with R^2 and the parameter uncertainties; the baseline computes it after its solve).  Numba
compilation is excluded (warm-up first).  The fitters take turns within each repeat so that changes in the
machine's load hit both alike.

BLAS threads: the fits hold BLAS at one thread while they run (threadpoolctl, models/bouc_wen/fitting.py);
this script also holds the plain baseline at one thread (threadpoolctl), unless ``--blas-default``.

Run: ``python benchmarks/bench_bouc_wen.py [--repeats 5] [--blas-default] [--full]``
"""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import statistics
import time
from collections.abc import Callable

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_info, threadpool_limits

from protocol_runner.analysis.bouc_wen_fit import fit_configuration
from protocol_runner.models.bouc_wen import fitting as bw_fitting
from protocol_runner.models.bouc_wen import kernels as bw_kernels
from protocol_runner.models.bouc_wen.fitting import fit_trials
from protocol_runner.models.bouc_wen.params import BoucWenParams
from protocol_runner.models.bouc_wen.records import BoucWenFit
from protocol_runner.models.bouc_wen.simulation import simulate

FIG57 = BoucWenParams(A=0.2823, n=1.2065, beta=(0.013, 0.145, -0.1359, -0.0879, 0.0935, -0.0036))
RATE_HZ = 1000.0
TRIAL_S = 65.0
PERIOD_S = 8.17
RANGE_DEG = (0.0, 130.0)
NOISE_NM = 0.2
SEED = 2007

Segments = list[tuple[np.ndarray, np.ndarray]]


def make_configuration(seed: int = SEED) -> Segments:
    """Three centred trials of one configuration, torque from Eq 23 (Figure 57) plus noise."""
    rng = np.random.default_rng(seed)
    t_s = np.arange(0.0, TRIAL_S, 1.0 / RATE_HZ)
    lo, hi = RANGE_DEG
    segments: Segments = []
    for _ in range(3):
        angle_deg = lo + (hi - lo) * 0.5 * (1.0 - np.cos(2.0 * np.pi * t_s / PERIOD_S))
        angle_deg = angle_deg - angle_deg.mean()
        torque_nm = simulate(angle_deg, FIG57, z0=0.0) + NOISE_NM * rng.standard_normal(t_s.size)
        segments.append((angle_deg, torque_nm))
    return segments


def rmse_all_samples(segments: Segments, params: BoucWenParams) -> float:
    """RMSE over every given sample, each trial simulated from its own first torque."""
    sq = 0.0
    count = 0
    for x, y in segments:
        z = simulate(x, params, z0=float(y[0]))
        r = np.where(np.isfinite(z), z - y, 1e6)
        sq += float(r @ r)
        count += y.size
    return math.sqrt(sq / count)


def baseline_fit(
    segments: Segments, stride: tuple[int, ...], start: BoucWenParams | None = None
) -> tuple[BoucWenParams, int, float]:
    """Plain baseline: numba recursion + least_squares with its default 2-point Jacobian, from
    A = n = 1, betas = 0 unless ``start`` is given.  Returns the parameters, the number of residual
    evaluations and the RMSE on every given sample (the deliverable ``fit_trials`` also computes)."""
    xs = np.concatenate([x[::k] for (x, _), k in zip(segments, stride, strict=True)])
    ys = np.concatenate([y[::k] for (_, y), k in zip(segments, stride, strict=True)])
    seg = np.zeros(len(segments) + 1, dtype=np.int64)
    seg[1:] = np.cumsum([x[::k].size for (x, _), k in zip(segments, stride, strict=True)])
    z0 = np.ascontiguousarray(ys[seg[:-1]])
    bound = 10.0 * float(np.max(np.abs(ys)))
    z = np.empty_like(xs)

    def residuals(theta: np.ndarray) -> np.ndarray:
        shape = (theta[0], theta[1], theta[2:])
        bw_kernels.kernel(
            xs, seg, z0, shape, (bound, True, 0.0, False), z, bw_kernels.NO_SENSITIVITY, False, False
        )
        return z - ys

    x0 = np.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]) if start is None else start.as_array()
    res = least_squares(residuals, x0)
    params = BoucWenParams.from_array(res.x)
    return params, int(res.nfev), rmse_all_samples(segments, params)


def timed_interleaved(fns: list[Callable[[], object]], repeats: int) -> list[tuple[float, object]]:
    """Median wall time of each function; the functions take turns within every repeat, so that a change
    in the machine's load (other processes) affects all of them alike."""
    times: list[list[float]] = [[] for _ in fns]
    outs: list[object] = [None] * len(fns)
    for _ in range(repeats):
        for k, fn in enumerate(fns):
            t0 = time.perf_counter()
            outs[k] = fn()
            times[k].append(time.perf_counter() - t0)
    return [(statistics.median(t), out) for t, out in zip(times, outs, strict=True)]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument(
        "--blas-default", action="store_true", help="leave the baseline's BLAS threading at its default"
    )
    parser.add_argument(
        "--full", action="store_true", help="also fit every 1 kHz sample once (the cost of not decimating)"
    )
    args = parser.parse_args()

    blas = contextlib.nullcontext() if args.blas_default else threadpool_limits(limits=1, user_api="blas")
    with blas:
        return run(args)


def run(args: argparse.Namespace) -> int:
    segments = make_configuration()
    n_given = sum(x.size for x, _ in segments)

    # warm-up: compile / load the numba kernels, outside the timings
    fit_trials([(x[:2000], y[:2000]) for x, y in segments[:1]])
    ours0 = fit_trials(segments)
    baseline_fit(segments, ours0.stride)

    stride = ours0.stride
    # for information: the thesis's own procedure, Figure 56's data-driven start + the same plain solver
    xs, ys, seg, _ = bw_fitting.decimate(segments, max(x[:: stride[0]].size for x, _ in segments))
    fig56 = bw_fitting.thesis_start(xs, ys, seg)
    fit_configuration(segments, cross_validate_trials=False)  # warm-up of the identifiability kernels
    timings = timed_interleaved(
        [
            lambda: fit_trials(segments),
            lambda: baseline_fit(segments, stride),
            lambda: baseline_fit(segments, stride, fig56),
            lambda: fit_trials(segments, scheme="eq23"),
            lambda: fit_configuration(segments, cross_validate_trials=False),
            lambda: fit_configuration(segments),
        ],
        args.repeats,
    )
    (t_ours, ours_out), (t_base, base_out), (t_f56, f56_out) = timings[:3]
    (t_eq23, eq23_out), (t_config, config_out), (t_cv, cv_out) = timings[3:]
    assert isinstance(cv_out, tuple)
    assert isinstance(eq23_out, BoucWenFit) and isinstance(config_out, tuple)
    config_fit: BoucWenFit = config_out[0]
    ours = ours_out
    assert isinstance(ours, BoucWenFit) and ours.stride == stride
    assert isinstance(base_out, tuple) and isinstance(f56_out, tuple)
    base_params: BoucWenParams = base_out[0]
    base_nfev: int = base_out[1]
    rmse_base: float = base_out[2]
    f56_nfev: int = f56_out[1]
    rmse_f56: float = f56_out[2]

    rmse_ours = rmse_all_samples(segments, ours.params)
    assert abs(rmse_ours - ours.rmse_nm) <= 1e-9 * rmse_ours
    rmse_truth = rmse_all_samples(segments, FIG57)

    threads = [
        f"{i['internal_api']} {i['num_threads']}" for i in threadpool_info() if i["user_api"] == "blas"
    ]
    print(f"BLAS threads outside the fits: {', '.join(threads)}; load average {os.getloadavg()[0]:.2f}")
    print(
        f"data: 3 trials x {TRIAL_S:.0f} s at {RATE_HZ:.0f} Hz = {n_given} samples, "
        f"noise {NOISE_NM} N*m; both fitters used every {ours.stride[0]}th sample "
        f"({ours.n_samples_fitted} samples); RMSE on all {n_given} samples; median of {args.repeats}"
    )
    print()
    print(f"{'fitter':<34}{'median time (s)':>16}{'RMSE (N*m)':>14}{'nfev':>8}")
    print(f"{'ours: fit_trials (analytic J)':<34}{t_ours:>16.3f}{rmse_ours:>14.6f}{ours.nfev:>8d}")
    print(f"{'baseline: least_squares 2-point J':<34}{t_base:>16.3f}{rmse_base:>14.6f}{base_nfev:>8d}")
    print(f"{'(info) Figure 56 start + 2-point J':<34}{t_f56:>16.3f}{rmse_f56:>14.6f}{f56_nfev:>8d}")
    if args.full:
        t0 = time.perf_counter()
        full = fit_trials(segments, max_samples_per_trial=None)
        t_full = time.perf_counter() - t0
        print(
            f"{'(info) ours on every sample, 1 run':<34}{t_full:>16.3f}{full.rmse_nm:>14.6f}{full.nfev:>8d}"
        )
    print(f"{'(info) true Figure 57 parameters':<34}{'':>16}{rmse_truth:>14.6f}")
    print()
    print("the thesis's Eq 23 fit against the configuration fit with its evidence, same run")
    print(f"{'fit':<46}{'median time (s)':>16}{'RMSE':>10}{'4x finer':>10}")
    print(
        f"{'Eq 23: fit_trials(scheme=eq23)':<46}{t_eq23:>16.3f}"
        f"{eq23_out.rmse_nm:>10.4f}{eq23_out.rmse_refined_nm:>10.4f}"
    )
    print(
        f"{'fit_configuration (refined, intervals)':<46}{t_config:>16.3f}"
        f"{config_fit.rmse_nm:>10.4f}{config_fit.rmse_refined_nm:>10.4f}"
    )
    cv_text = ", ".join(f"{e:.4f}" for e in cv_out[1])
    print(f"{'(info) the same with cross-validation':<46}{t_cv:>16.3f}  held-out RMSE {cv_text}")
    print()
    print("fitted (ours):   ", np.array2string(ours.params.as_array(), precision=5))
    print("fitted (baseline):", np.array2string(base_params.as_array(), precision=5))
    print("Figure 57:        ", np.array2string(FIG57.as_array(), precision=5))
    print()
    checks = [
        (f"ours median time < 0.5 s ({t_ours:.3f} s)", t_ours < 0.5),
        (
            f"ours RMSE not worse than baseline ({rmse_ours:.5f} <= {rmse_base:.5f} N*m, rel. tol 1e-6)",
            rmse_ours <= rmse_base * (1.0 + 1e-6),
        ),
        (f"ours time <= 2x baseline ({t_ours:.3f} <= {2 * t_base:.3f} s)", t_ours <= 2.0 * t_base),
        (f"configuration fit with its evidence < 0.5 s ({t_config:.3f} s)", t_config < 0.5),
        (
            f"its 4x-finer RMSE within 2 % ({config_fit.rmse_refined_nm:.4f} vs {config_fit.rmse_nm:.4f} N*m)",
            abs(config_fit.rmse_refined_nm - config_fit.rmse_nm) <= 0.02 * config_fit.rmse_nm,
        ),
    ]
    for label, ok in checks:
        print(f"{'PASS' if ok else 'FAIL'}  {label}")
    return 0 if all(ok for _, ok in checks) else 1


if __name__ == "__main__":
    raise SystemExit(main())
