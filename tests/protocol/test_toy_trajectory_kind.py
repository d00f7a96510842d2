"""docs/architecture.md's recipe for a trajectory kind, followed in a test: a kind whose model (fields, build,
sampling, limit checks) is registered in the test - nothing else in the program knows it - is accepted
in a protocol file, planned, checked against the joint's limits by field, and commanded by a dry run;
then removed, after which a protocol naming it is refused again."""

from __future__ import annotations

import math
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import ClassVar, Literal

import h5py
import numpy as np
import pytest
from pydantic import Field

from protocol_runner.commands import run
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import TrialStep
from protocol_runner.protocol.plan_table import format_plan_table
from protocol_runner.protocol.stream_check import LimitCheck
from protocol_runner.protocol.trajectory_record import Trajectory
from protocol_runner.protocol.trajectory_specs import (
    BindableRange,
    BuildContext,
    Fields,
    FloatArray,
    TrajectoryKindSpec,
    deregister_trajectory_kind,
    register_trajectory_kind,
)

KEY = 7  # elbow_example's configuration on its `tri` trajectory


class CosineWaveSpec(TrajectoryKindSpec):
    """The toy kind: lo + (hi - lo) * (1 - cos(2*pi*t/period)) / 2, from rest at the low end; its peak speed
    is pi*(hi - lo)/period and its peak acceleration 2*pi^2*(hi - lo)/period^2."""

    kind: Literal["cosine_wave"]
    range_deg: BindableRange
    period_s: float = Field(gt=0)
    cycles: float = Field(gt=0)

    bindable: ClassVar[tuple[str, ...]] = ("range_deg",)
    length_field: ClassVar[str] = "cycles"

    def build(self, fields: Fields, at: BuildContext) -> Trajectory:
        span = fields["range_deg"]
        assert isinstance(span, tuple)
        return Trajectory(
            profile="cosine_wave",
            params=(("range_deg", span), ("period_s", self.period_s)),
            duration_s=self.cycles * self.period_s,
        )

    @staticmethod
    def sample(trajectory: Trajectory, time_s: FloatArray, base_dir: Path) -> FloatArray:
        lo, hi = trajectory.param("range_deg")  # type: ignore[misc]
        wave: FloatArray = (
            lo + (hi - lo) * (1.0 - np.cos(2.0 * np.pi * time_s / trajectory.number("period_s"))) / 2
        )
        return wave

    @staticmethod
    def check_limits(trajectory: Trajectory, check: LimitCheck) -> None:
        lo, hi = trajectory.param("range_deg")  # type: ignore[misc]
        period = trajectory.number("period_s")
        check.range("range_deg", lo, hi)
        check.rate("period_s", math.pi * (hi - lo) / period, "its peak speed pi*range/period")
        check.accel(
            "period_s", 2 * math.pi**2 * (hi - lo) / period**2, "its peak acceleration 2*pi²*range/period²"
        )


@pytest.fixture
def cosine_wave() -> Iterator[None]:
    register_trajectory_kind(CosineWaveSpec)
    yield
    deregister_trajectory_kind("cosine_wave")


def protocol_with(tmp_path: Path, trajectory: str) -> Path:
    """elbow_example with its `tri` trajectory replaced by `trajectory` (its files copied beside it)."""
    source = find_protocol("elbow_example.yaml")
    folder = tmp_path / "protocols"
    shutil.copytree(source.parent, folder)
    text = source.read_text()
    old = "tri: {kind: triangle, range_deg: [20, 110], speed_deg_s: speed.speed_deg_s, cycles: 4}"
    assert old in text
    path = folder / "elbow_example.yaml"
    path.write_text(text.replace(old, f"tri: {trajectory}"))
    return path


def test_a_registered_trajectory_kind_is_planned_checked_and_commanded(
    cosine_wave: None, tmp_path: Path
) -> None:
    path = protocol_with(tmp_path, "{kind: cosine_wave, range_deg: [20, 110], period_s: 8, cycles: 4}")
    loaded = load_protocol(path)
    plan = expand(loaded, only=[KEY])
    trials = [s for s in plan.steps if isinstance(s, TrialStep)]
    assert trials and all(t.trajectory.profile == "cosine_wave" for t in trials)
    assert trials[0].trajectory.duration_s == 32.0

    # --plan: the matrix names the kind, each trial its profile (the default description of a kind)
    table = format_plan_table(plan)
    assert "tri (cosine_wave)" in table
    assert sum(1 for line in table.splitlines() if "  cosine_wave" in line) == len(trials)

    # its own limit check, by field: a 1 s period is too fast for the elbow's rate and acceleration limits
    fast = protocol_with(
        tmp_path / "fast", "{kind: cosine_wave, range_deg: [20, 110], period_s: 1, cycles: 4}"
    )
    with pytest.raises(InvalidInput) as refused:
        load_protocol(fast)
    assert "trajectories.tri.period_s" in refused.value.message
    assert (
        "its peak speed pi*range/period 282.7 deg/s is over the joint's rate limit" in refused.value.message
    )

    # a dry run commands the kind's samples and processes the configuration
    session = tmp_path / "session"
    assert (
        run(
            str(path), dry_run=True, session=session, seed=7, yes=True, only=[KEY], realtime=False, quiet=True
        )
        == 0
    )
    with h5py.File(session / "archive.h5", "r") as f:
        config = f[f"configurations/config_{KEY:02d}"]
        assert config.attrs["profile"] == "cosine_wave"
        command = config["trials/1/brace_on/joints/elbow_flexion/command_deg"][:]
        assert command.min() >= 20.0 - 1e-9 and command.max() <= 110.0 + 1e-9
        assert command.max() > 109.9  # it reached the top of its range
        assert f.attrs["status"] == "complete"


def test_a_kind_removed_from_the_registry_is_refused_by_the_protocol_file(tmp_path: Path) -> None:
    register_trajectory_kind(CosineWaveSpec)
    with pytest.raises(ValueError, match="already registered"):
        register_trajectory_kind(CosineWaveSpec)
    deregister_trajectory_kind("cosine_wave")
    path = protocol_with(tmp_path, "{kind: cosine_wave, range_deg: [20, 110], period_s: 8, cycles: 4}")
    with pytest.raises(
        InvalidInput, match=r"trajectories\.tri: unknown kind 'cosine_wave' \(known: 'sinusoid'"
    ):
        load_protocol(path)
