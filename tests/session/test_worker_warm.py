"""session/worker_warm.py: a worker forked from the fork server starts with the Bouc-Wen kernels
compiled and loaded, the model simulation loaded and the figure canvases built (issue 20)."""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import pytest

from .python_child import child_stdout

SRC = Path(__file__).resolve().parents[2] / "src"

PROBE = """
import sys
sys.path.insert(0, {src!r})
from concurrent.futures import ProcessPoolExecutor
from protocol_runner.session.worker_start import start_worker_server, worker_context
start_worker_server()
probes = [
    "len(__import__('protocol_runner.models.bouc_wen.kernels', fromlist=['x']).heun_sensitivity_kernel.signatures)",
    "len(__import__('protocol_runner.models.bouc_wen.kernels', fromlist=['x']).heun_kernel.signatures)",
    "__import__('protocol_runner.report.figures', fromlist=['x']).warm_up.cache_info().currsize",
    "'protocol_runner.session.worker_warm' in __import__('sys').modules",
]
with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
    print(*(pool.submit(eval, p).result() for p in probes))
"""


def test_a_new_worker_has_the_fit_kernels_and_figures_warm() -> None:
    """Before it has run anything, a worker forked from the server has the fit's compiled kernels (a
    signature each), the canvases built (warm_up done once) and the warm-up module loaded: the server
    ran the first calls, not each worker."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork server here: spawned workers import everything themselves")
    out = child_stdout(PROBE.format(src=str(SRC))).split()
    assert int(out[0]) >= 1 and int(out[1]) >= 1
    assert out[2] == "1" and out[3] == "True"
