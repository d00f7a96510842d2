"""Single-threaded BLAS while a Bouc-Wen fit runs.

The solver's linear algebra works on tall, 8-column Jacobians (an SVD per trust-region step, products):
too little work per call to share between threads, so a multi-threaded BLAS spends each call handing work
back and forth, and on a loaded two-core machine (two analysis workers beside the session) it
oversubscribes the cores; the same fit then takes several times longer.  The fit's entry points therefore
hold every loaded BLAS library at one thread for their duration and restore the caller's setting after.

``threadpoolctl`` does this at run time through each library's own API, so it works whenever numpy was
imported (a notebook, pytest, a user's script); environment variables such as ``OPENBLAS_NUM_THREADS`` are
read only when the library loads and do nothing afterwards.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, ParamSpec, TypeVar

from threadpoolctl import ThreadpoolController

P = ParamSpec("P")
R = TypeVar("R")

_controller: ThreadpoolController | None = None


def _get_controller() -> ThreadpoolController:
    """One controller per process (finding the loaded libraries takes milliseconds; limiting them, tens of
    microseconds).  It is made at the first fit, after numpy and scipy have loaded their BLAS."""
    global _controller
    if _controller is None:
        _controller = ThreadpoolController()
    return _controller


def single_threaded_blas() -> Any:
    """Context manager: every loaded BLAS at one thread inside, the previous limits restored after."""
    return _get_controller().limit(limits=1, user_api="blas")


def blas_single_threaded(fn: Callable[P, R]) -> Callable[P, R]:
    """Run ``fn`` under :func:`single_threaded_blas`."""

    @functools.wraps(fn)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with single_threaded_blas():
            return fn(*args, **kwargs)

    return wrapper
