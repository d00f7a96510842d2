"""An analysis worker runs BLAS single-threaded for its whole life: two workers share the
cores with the session, so a multi-threaded BLAS in each would oversubscribe them.  Set by threadpoolctl
in the worker's initializer (after numpy and scipy loaded their BLAS), not by environment variables."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

from protocol_runner.session.workers import worker_init


def _blas_threads() -> list[int]:
    import scipy.linalg  # noqa: F401  (as a fit would have loaded it)
    from threadpoolctl import threadpool_info

    return [int(i["num_threads"]) for i in threadpool_info() if i["user_api"] == "blas"]


def test_an_analysis_worker_runs_blas_on_one_thread() -> None:
    pool = ProcessPoolExecutor(
        max_workers=1, mp_context=multiprocessing.get_context("spawn"), initializer=worker_init
    )
    try:
        threads = pool.submit(_blas_threads).result(timeout=120)
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
    assert threads and all(t == 1 for t in threads)
