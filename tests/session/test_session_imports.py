"""What the session process loads to start: the processing and the fits run in the analysis workers, which
import them in their fork server on the other core; the report's figures and predictions are made at the end
on processes of the report's own. The session imports its runner
without scipy's signal, optimisation and statistics packages, the Bouc-Wen model or matplotlib; a step kind
loads its module (and what that needs) when it first runs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

HEAVY = ("scipy.signal", "scipy.stats", "scipy.optimize", "matplotlib", "protocol_runner.analysis.pipeline")


def _loaded_after(code: str) -> set[str]:
    repo = Path(__file__).resolve().parents[2]
    env = {**os.environ, "PYTHONPATH": str(repo / "src")}
    probe = f"{code}\nimport json, sys\nprint(json.dumps(sorted(sys.modules)))"
    done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, check=True)
    return set(json.loads(done.stdout.strip().splitlines()[-1]))


def test_the_session_runner_and_its_step_kinds_load_no_analysis() -> None:
    loaded = _loaded_after(
        "import protocol_runner.commands, protocol_runner.session.runner, protocol_runner.steps.failures\n"
        "import protocol_runner.protocol.processing, protocol_runner.archive.results"
    )
    assert "protocol_runner.steps.registry" in loaded and "protocol_runner.session.workers" in loaded
    assert not loaded & set(HEAVY)
    assert not any(m.startswith("protocol_runner.models.bouc_wen") for m in loaded)


def test_a_step_kind_loads_its_module_when_it_first_runs() -> None:
    loaded = _loaded_after(
        "from protocol_runner.steps.registry import step_function\nstep_function('calibration_check.run')"
    )
    assert "protocol_runner.steps.calibration_check" in loaded
    assert "protocol_runner.steps.process" not in loaded and "protocol_runner.steps.fit" not in loaded


def test_the_predictions_a_worker_hands_back_load_no_model_in_the_session() -> None:
    """The session unpickles the `Prediction`s made on the report's own process at the end: their module
    imports the compiled Bouc-Wen model only where a prediction is computed."""
    loaded = _loaded_after(
        "import pickle\nfrom protocol_runner.report.predictions import Prediction\n"
        "back = pickle.loads(pickle.dumps(Prediction(1, 2, 'note', 0.5, 0.4)))\n"
        "assert back == Prediction(1, 2, 'note', 0.5, 0.4)"
    )
    assert "protocol_runner.report.predictions" in loaded
    assert not any(m.startswith("protocol_runner.models.bouc_wen") for m in loaded)
