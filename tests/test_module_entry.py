"""`python -m protocol_runner` is the `run-protocol` command; the package says it is typed."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import protocol_runner

REPO = Path(__file__).resolve().parents[1]


def test_python_dash_m_runs_the_command() -> None:
    done = subprocess.run(
        [
            sys.executable,
            "-m",
            "protocol_runner",
            "--validate",
            str(REPO / "protocols" / "elbow_example.yaml"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert "elbow_example.yaml: valid." in done.stdout


def test_python_dash_m_exits_2_on_a_missing_file(tmp_path: Path) -> None:
    done = subprocess.run(
        [sys.executable, "-m", "protocol_runner", "--validate", str(tmp_path / "nothing.yaml")],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2
    assert "not found" in done.stderr and "Traceback" not in done.stderr


def test_the_package_ships_its_type_information() -> None:
    """PEP 561: a `py.typed` marker beside the package, so a lab's own scripts are type-checked against it."""
    assert (Path(protocol_runner.__file__).parent / "py.typed").is_file()
