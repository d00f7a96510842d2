"""The analysis workers' first-call costs, paid once by their fork server (issue 20), imported last of
`worker_start.PRELOADED`.

A worker's first filter and first Bouc-Wen fit load the compiled kernels from numba's cache, and the fit
takes scipy's solver through its first call; its first figure loads fonts and builds the canvases; its
first model prediction loads the compiled simulation. Done in every worker, that is about 0.2 s of CPU
each, spent while the session waits on them. The fork server does it once instead, on synthetic data,
before it forks any worker: the workers inherit the loaded code and warm caches (fork copies the
server's memory). The server has the time: it is ready well before the first configuration's trials are
recorded, its core otherwise idle meanwhile.

Nothing here is written anywhere, and nothing computed here reaches a result: a worker's analyses are
the same numbers with or without it (the compiled code is the same, loaded earlier). Any failure is
ignored: a worker then pays its first calls itself, as without this module. Importing this module does
the warm-up; only the fork server imports it.
"""

from __future__ import annotations

import contextlib

import numpy as np

from .heap import settle

WARM_UP_SAMPLES = 120  # a short synthetic loop: enough for every stage of the fit to run once


def warm_up() -> None:
    """Run a tiny zero-phase filter, fit, identification and cross-validation, a model prediction and one
    figure of each canvas, discarding the results."""
    with contextlib.suppress(Exception):
        _filter()
    with contextlib.suppress(Exception):
        _fit()
    with contextlib.suppress(Exception):
        from ..report.predictions import warm_up as predictions

        predictions()
    with contextlib.suppress(Exception):
        from ..report.figures import warm_up as figures

        figures()


def _filter() -> None:
    from ..analysis.filters import design_lowpass, filter_zero_phase

    filter_zero_phase(np.sin(np.linspace(0.0, 6.0, 4 * WARM_UP_SAMPLES)), design_lowpass())


def _fit() -> None:
    from ..models.bouc_wen import cross_validate, fit_trials
    from ..models.bouc_wen.identifiability import identify

    angle_deg = 30.0 * np.sin(np.linspace(0.0, 4.0 * np.pi, WARM_UP_SAMPLES))
    torque_nm = 0.5 * angle_deg + 5.0 * np.tanh(np.gradient(angle_deg))
    trials = [(angle_deg, torque_nm), (angle_deg, torque_nm)]
    fit = fit_trials(trials, starts=1, backbone_degree=3)
    identify(trials, fit)
    cross_validate(trials, starts=1, backbone_degree=3)


warm_up()
settle()  # what the workers inherit stays out of their collections (session/heap.py)
