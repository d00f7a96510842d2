"""Time split of a dry run, by process (loaded only when bench_time_split.py puts this folder on PYTHONPATH).

Every Python process of the run (the session, its analysis workers, the report's figure workers) wraps a
few functions as their modules are imported and appends one line per call to $PR_SPLIT_LOG:
``pid thread category wall_seconds cpu_seconds`` (the CPU time of the calling thread: the h5py compression
threads' share of a unit write is not in it). Every thread started with `threading.Thread` (and not
overriding `run`) also writes ``pid name thread_start native_id 0`` as it starts, so that the benchmark can
name the threads whose CPU it reads from /proc. Nothing is wrapped when PR_SPLIT_LOG is unset.
"""

from __future__ import annotations

import functools
import importlib.abc
import importlib.machinery
import os
import sys
import threading
import time

LOG = os.environ.get("PR_SPLIT_LOG")
TARGETS = {
    "protocol_runner.hardware.rig": [("Rig", "send", "acquisition")],
    "protocol_runner.archive.units": [(None, "write_unit", "writing")],
    "protocol_runner.steps.process": [(None, "run", "processing")],
    "protocol_runner.steps.fit": [(None, "run", "fits")],
    "protocol_runner.session.assembly": [(None, "consolidate_session", "consolidation")],
    "protocol_runner.session.reporting": [(None, "render_report", "report")],
    "protocol_runner.report.load": [(None, "load_report_data", "report: reading the archive")],
    "protocol_runner.session.runner": [("Runner", "_run", "session")],
    "protocol_runner.steps.trial": [(None, "run", "trial steps (acquisition included)")],
    "protocol_runner.steps.calibration_check": [(None, "run", "calibration steps")],
    "protocol_runner.session.workers": [
        ("AnalysisPool", "collect", "waiting for the analyses"),
    ],
}


def _wrap(func, category):  # type: ignore[no-untyped-def]
    @functools.wraps(func)
    def timed(*args, **kwargs):  # type: ignore[no-untyped-def]
        t0, c0 = time.perf_counter(), time.thread_time()
        try:
            return func(*args, **kwargs)
        finally:
            dt, dc = time.perf_counter() - t0, time.thread_time() - c0
            with open(LOG, "a") as f:  # type: ignore[arg-type]
                f.write(
                    f"{os.getpid()} {threading.current_thread().name} {category.replace(' ', '_')} {dt:.6f} {dc:.6f}\n"
                )

    return timed


class _Loader(importlib.abc.Loader):
    def __init__(self, inner: importlib.abc.Loader, name: str) -> None:
        self.inner, self.name = inner, name

    def create_module(self, spec):  # type: ignore[no-untyped-def]
        return self.inner.create_module(spec)

    def exec_module(self, module):  # type: ignore[no-untyped-def]
        self.inner.exec_module(module)
        for owner, attr, category in TARGETS[self.name]:
            holder = getattr(module, owner) if owner else module
            setattr(holder, attr, _wrap(getattr(holder, attr), category))


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path, target=None):  # type: ignore[no-untyped-def]
        if name not in TARGETS:
            return None
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is not None and spec.loader is not None:
            spec.loader = _Loader(spec.loader, name)
        return spec


def _log_thread_start(run):  # type: ignore[no-untyped-def]
    @functools.wraps(run)
    def logged(self):  # type: ignore[no-untyped-def]
        with open(LOG, "a") as f:  # type: ignore[arg-type]
            f.write(
                f"{os.getpid()} {self.name.replace(' ', '_')} thread_start {threading.get_native_id()} 0\n"
            )
        return run(self)

    return logged


if LOG:
    sys.meta_path.insert(0, _Finder())
    threading.Thread.run = _log_thread_start(threading.Thread.run)  # type: ignore[method-assign]
    with open(LOG, "a") as f:
        f.write(f"{os.getpid()} MainThread process_start {time.time():.6f} 0\n")
