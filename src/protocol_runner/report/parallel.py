"""Run report work on forked worker processes, falling back to the caller when that is not possible.

Reading a full campaign's trials and drawing ~140 figures are CPU-bound and independent per item, so two
processes on a 2-core machine nearly halve the report's regeneration time. Fork (not spawn) is used so
workers start in milliseconds with the parent's modules and data already in memory; where fork is not
available (Windows) or the pool breaks, `map_in_processes` returns None and the caller runs serially.
"""

from __future__ import annotations

import multiprocessing
import warnings
from collections.abc import Callable, Iterable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, TypeVar

T = TypeVar("T")
R = TypeVar("R")


def map_in_processes(
    fn: Callable[[T], R],
    items: Iterable[T],
    workers: int,
    *,
    initializer: Callable[..., None] | None = None,
    initargs: tuple[Any, ...] = (),
    chunksize: int = 1,
) -> list[R] | None:
    """`[fn(item) for item in items]` on `workers` forked processes, in order; None if forking fails.

    `fn` and the items must be picklable (module-level functions); `initializer(*initargs)` runs once in
    each worker (with fork, `initargs` are inherited, not pickled). Exceptions raised by `fn` propagate.
    """
    try:
        ctx = multiprocessing.get_context("fork")
    except ValueError:  # no fork on this platform
        return None
    try:
        with warnings.catch_warnings():
            # Python >= 3.12 warns that forking a multi-threaded process (BLAS threads count) may
            # deadlock; the workers only compute and never take a lock another thread could hold.
            warnings.simplefilter("ignore", DeprecationWarning)
            with ProcessPoolExecutor(
                max_workers=workers, mp_context=ctx, initializer=initializer, initargs=initargs
            ) as pool:
                return list(pool.map(fn, items, chunksize=chunksize))
    except (BrokenProcessPool, OSError):
        return None
