"""The `run-protocol` process starts OpenBLAS with one thread (cli.one_blas_thread) unless told otherwise."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

SRC = Path(__file__).resolve().parents[1] / "src"

CHILD = """
import json, os, sys
import protocol_runner.cli as cli
before = "numpy" in sys.modules or "scipy" in sys.modules
cli.one_blas_thread()
import numpy, scipy.linalg
from threadpoolctl import threadpool_info
print(json.dumps({
    "imported_before": before,
    "env": os.environ.get("OPENBLAS_NUM_THREADS"),
    "threads": [p["num_threads"] for p in threadpool_info() if p["internal_api"] == "openblas"],
}))
"""


def _child(env_value: str | None) -> dict[str, object]:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if env_value is not None:
        env["OPENBLAS_NUM_THREADS"] = env_value
    env["PYTHONPATH"] = os.pathsep.join([str(SRC), env.get("PYTHONPATH", "")])
    done = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    result: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return result


def test_the_command_starts_openblas_with_one_thread_before_numpy_loads() -> None:
    seen = _child(None)
    assert seen["imported_before"] is False  # the command line loads no numpy before it is set
    assert seen["env"] == "1"
    threads = seen["threads"]
    assert isinstance(threads, list) and threads  # numpy's and scipy's OpenBLAS
    assert set(threads) == {1}


def test_a_thread_count_the_user_set_is_kept() -> None:
    assert _child("2")["env"] == "2"
