"""Preflight warnings: a processed trial whose commanded angle holds no complete cycle is named before the
run (file, line, field), by `--validate`, `--plan` and the run itself, and stops nothing."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.analysis.cycles import complete_cycles
from protocol_runner.cli import main
from protocol_runner.preflight import preflight_warnings
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.sampling import sample_trajectory
from protocol_runner.resources import packaged_protocols_dir

from ..multi.test_multi_protocol import LEG_TEXT

ELBOW = (packaged_protocols_dir() / "elbow_example.yaml").read_text(encoding="utf-8")
SINE_LINE = "  sine: {kind: sinusoid, range_deg: [20, 110], speed_deg_s: speed.speed_deg_s, periods: 6}"


def elbow_with(tmp_path: Path, periods: str, triangle_cycles: str = "4") -> Path:
    assert SINE_LINE in ELBOW
    text = ELBOW.replace(SINE_LINE, SINE_LINE.replace("periods: 6", f"periods: {periods}"))
    text = text.replace("speed.speed_deg_s, cycles: 4}", f"speed.speed_deg_s, cycles: {triangle_cycles}}}")
    path = tmp_path / "elbow.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def warnings_of(path: Path) -> list[str]:
    loaded = load_protocol(path)
    return preflight_warnings(loaded, expand(loaded))


def test_two_periods_of_a_sinusoid_hold_no_cycle_and_are_named_at_their_field(tmp_path: Path) -> None:
    path = elbow_with(tmp_path, "2")
    line = (
        path.read_text(encoding="utf-8").splitlines().index(SINE_LINE.replace("periods: 6", "periods: 2")) + 1
    )
    (warning,) = warnings_of(path)
    assert warning.startswith(f"{path}:{line}: trajectories.sine.periods: warning: ")
    assert "configurations 1-6" in warning and "7" not in warning.split("(")[1].split(")")[0]
    assert "at least 3 periods" in warning and "it commands 2" in warning


def test_three_periods_give_one_cycle_and_no_warning(tmp_path: Path) -> None:
    assert warnings_of(elbow_with(tmp_path, "3")) == []
    assert warnings_of(elbow_with(tmp_path, "6")) == []


def test_the_warning_follows_the_processing_rule_on_the_commanded_samples(tmp_path: Path) -> None:
    """The rule itself: the analysis's complete cycles of the sampled commands, 0 for 2 periods and
    periods - 2 from 3 on (a sinusoid starts at its mean moving up: that crossing has no low side)."""
    for periods in (2, 3, 4, 6):
        loaded = load_protocol(elbow_with(tmp_path, str(periods)))
        step = next(s for s in expand(loaded).steps if s.kind == "trial" and s.trajectory.name == "sine")
        angle = sample_trajectory(step.trajectory, loaded.protocol.rig.output.rate_hz, loaded.base_dir)
        assert len(complete_cycles(angle)) == periods - 2
        assert bool(warnings_of(elbow_with(tmp_path, str(periods)))) == (periods == 2)


def test_a_triangle_of_one_cycle_is_named_too(tmp_path: Path) -> None:
    (warning,) = warnings_of(elbow_with(tmp_path, "6", triangle_cycles="1"))
    assert re.search(r"trajectories\.tri: warning: trajectory 'tri' commands no complete cycle", warning)
    assert "(configuration 7)" in warning and "lengthen the motion" in warning


def test_validate_and_plan_print_it_and_still_succeed(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = elbow_with(tmp_path, "2")
    assert main(["--validate", str(path)]) == 0
    out, err = capsys.readouterr()
    assert ": valid." in out
    assert "trajectories.sine.periods: warning: trajectory 'sine' commands no complete cycle" in err
    assert main(["--plan", str(path), "--only", "1"]) == 0
    out, err = capsys.readouterr()
    assert "warning: trajectory 'sine'" in err and "(configuration 1)" in err
    assert main(["--plan", str(path), "--only", "7"]) == 0  # the triangle's configuration alone: nothing
    assert "warning" not in capsys.readouterr().err


def test_the_shipped_campaigns_warn_of_nothing() -> None:
    for name in ("knee_phase1", "ankle_phase2", "elbow_example", "leg_phase2"):
        assert warnings_of(packaged_protocols_dir() / f"{name}.yaml") == [], name


def test_complete_cycles_of_a_sampled_sine_count_periods_minus_two() -> None:
    """The fact the hint states, on the rule alone: sin from its mean moving up, N periods -> N - 2."""
    t = np.arange(0.0, 10.0, 0.01)
    for n in (2, 3, 5):
        angle = 60.0 + 20.0 * np.sin(2.0 * np.pi * n * t / 10.0)
        assert len(complete_cycles(angle)) == n - 2


def test_each_joint_of_a_per_joint_motion_is_named(tmp_path: Path) -> None:
    shutil.copytree(packaged_protocols_dir() / "trajectories", tmp_path / "trajectories")
    line = "  sit_to_stand: {kind: file, file: trajectories/leg_sit_to_stand_synthetic.csv}"
    assert line in LEG_TEXT
    text = LEG_TEXT.replace(
        line,
        "  sit_to_stand:\n    kind: per_joint\n    joints:\n"
        "      hip_flexion: {kind: sinusoid, range_deg: [10, 40], speed_deg_s: 15, periods: 2}\n"
        "      knee_flexion: {kind: sinusoid, range_deg: [20, 90], speed_deg_s: 35, periods: 2}\n"
        "      ankle_flexion: {kind: sinusoid, range_deg: [-10, 10], speed_deg_s: 10, periods: 2}",
    )
    path = tmp_path / "leg.yaml"
    path.write_text(text, encoding="utf-8")
    warnings = warnings_of(path)
    assert len(warnings) == 3
    for joint, warning in zip(("hip_flexion", "knee_flexion", "ankle_flexion"), warnings, strict=True):
        assert f": trajectories.sit_to_stand.joints.{joint}.periods: warning: " in warning
        assert f"(configuration 3, joint {joint})" in warning
    path.write_text(text.replace("periods: 2", "periods: 4"), encoding="utf-8")
    assert warnings_of(path) == []
