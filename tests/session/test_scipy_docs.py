"""session/scipy_docs.py: the session's and the fork server's scipy, imported without its array-API
docstring notes, computes exactly what it computes with them (issue 20)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from .python_child import child_stdout

SRC = Path(__file__).resolve().parents[2] / "src"

CHILD = """
import json, sys
sys.path.insert(0, {src!r})
from protocol_runner.session.scipy_docs import skip_array_api_notes
applied = skip_array_api_notes() if sys.argv[1] == "skip" else False
import numpy as np
import scipy.signal, scipy.optimize
x = np.sin(np.linspace(0.0, 20.0, 500)) + np.linspace(0.0, 1.0, 500) ** 3
sos = scipy.signal.butter(10, 0.1, output="sos")
y = scipy.signal.sosfiltfilt(sos, x)
root = scipy.optimize.minimize_scalar(lambda t: (t - 0.3) ** 2 + np.cos(5 * t)).x
doc = scipy.signal.sosfiltfilt.__doc__
print(json.dumps({{"applied": applied, "again": skip_array_api_notes(), "y": y.tobytes().hex(), "root": float(root).hex(),
                  "note": "Array API Standard Support" in doc, "doc": "second-order sections" in doc}}))
"""


def _child(mode: str) -> dict[str, object]:
    out = child_stdout(CHILD.format(src=str(SRC)), mode)
    result: dict[str, object] = json.loads(out.strip().splitlines()[-1])
    return result


def test_scipy_without_its_docstring_notes_computes_the_same_bits() -> None:
    """With the notes skipped, the filter and the solver the session uses give bit-identical results,
    the docstrings keep their text and lose only the note; a second call (scipy already imported) does
    nothing."""
    import scipy._lib._array_api as array_api

    if not hasattr(array_api, "xp_capabilities"):
        pytest.skip("this scipy adds no array-API notes to its docstrings")
    plain = _child("plain")
    skipped = _child("skip")
    assert skipped["applied"] is True and skipped["again"] is False and plain["again"] is False
    assert skipped["y"] == plain["y"] and skipped["root"] == plain["root"]
    assert plain["note"] is True and skipped["note"] is False
    assert plain["doc"] is True and skipped["doc"] is True


SESSION_AND_WORKER = """
import sys
sys.path.insert(0, {src!r})
from concurrent.futures import ProcessPoolExecutor
from protocol_runner import commands
from protocol_runner.session.worker_start import worker_context
commands._start_worker_server()  # what run and resume do first
import scipy._lib._array_api as array_api
probe = "__import__('scipy._lib._array_api', fromlist=['x']).FunctionDoc.__name__"
with ProcessPoolExecutor(1, mp_context=worker_context()) as pool:
    in_worker = pool.submit(eval, probe).result()
print(array_api.FunctionDoc.__name__, in_worker)
"""


def test_the_session_process_and_the_analysis_workers_skip_the_notes() -> None:
    """Both processes a command-line session owns apply it before they import scipy: the session where
    it starts its fork server (commands.py), the workers through their fork server (the first module it
    preloads)."""
    import scipy._lib._array_api as array_api

    if not hasattr(array_api, "xp_capabilities"):
        pytest.skip("this scipy adds no array-API notes to its docstrings")
    out = child_stdout(SESSION_AND_WORKER.format(src=str(SRC)))
    assert out.split() == ["_AsWritten", "_AsWritten"]
