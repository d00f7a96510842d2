"""Run report work on worker processes, falling back to the caller when that is not possible.

Reading a campaign's trials and drawing its figures are CPU-bound and independent per item. The workers are
a `ProcessPoolExecutor` with the platform's default start method; if processes cannot be started or the pool
breaks, `map_in_processes` returns None and the caller runs serially.
"""

from __future__ import annotations

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
    """`[fn(item) for item in items]` on `workers` processes, in order; None if the pool cannot run.

    `fn`, `initializer`, the items and `initargs` must be picklable (module-level functions, plain data);
    `initializer(*initargs)` runs once in each worker. Exceptions raised by `fn` propagate.
    """
    try:
        with ProcessPoolExecutor(max_workers=workers, initializer=initializer, initargs=initargs) as pool:
            return list(pool.map(fn, items, chunksize=chunksize))
    except (BrokenProcessPool, OSError):
        return None
