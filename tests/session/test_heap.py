"""session/heap.py: a command-line session collects no garbage while it starts, then keeps what start-up
made out of later collections, and its analysis workers start that way too (issue 20). Each fact is
checked in a fresh interpreter: the test process's own collector is left alone."""

from __future__ import annotations

import multiprocessing
from pathlib import Path

import pytest

from .python_child import child_stdout

SRC = Path(__file__).resolve().parents[2] / "src"

STATES = """
import gc, sys
sys.path.insert(0, {src!r})
from protocol_runner.session import heap
before = gc.get_freeze_count()
heap.pause()
paused = gc.isenabled()
junk = [[i] for i in range(50_000)]  # tracked containers made while paused
heap.settle()
print(paused, gc.isenabled(), gc.get_freeze_count() - before >= 50_000)
gc.disable()  # a caller that had switched collections off itself
heap.pause()
heap.settle()
print(gc.isenabled())
"""


def test_pause_stops_collections_and_settle_freezes_what_is_alive_and_resumes() -> None:
    """Paused: no automatic collections. Settled: everything alive (here 50,000 lists made meanwhile) is in
    the permanent generation and collections run again. A collector switched off by the caller before
    the pause stays off."""
    first, second = child_stdout(STATES.format(src=str(SRC))).splitlines()
    assert first.split() == ["False", "True", "True"]
    assert second == "False"


WORKER = """
import gc, sys
sys.path.insert(0, {src!r})
from concurrent.futures import ProcessPoolExecutor
from protocol_runner.session import heap
from protocol_runner.session.worker_start import start_worker_server, worker_context
heap.pause()  # as the command line does before it forks its fork server
start_worker_server(fork_session=True)
heap.settle()
probe = "(__import__('gc').isenabled(), __import__('gc').get_freeze_count())"
with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
    enabled, frozen = pool.submit(eval, probe).result()
print(gc.isenabled(), enabled, frozen > 100_000)
"""


def test_workers_of_a_paused_session_collect_again_with_the_servers_heap_frozen() -> None:
    """The fork server, forked while the session is paused, settles after its warm-up: a worker it forks
    has collections on, and the modules, kernels and canvases it inherited (hundreds of thousands of
    objects) frozen out of them."""
    if "forkserver" not in multiprocessing.get_all_start_methods():
        pytest.skip("no fork server here: spawned workers import everything themselves")
    out = child_stdout(WORKER.format(src=str(SRC))).split()
    assert out == ["True", "True", "True"]
