"""A brace-off trial takes its brace-on twin's recording from memory when the same process ran the twin
(it used to read the unit back from disk), and that memory is exactly what the unit stores: the
same dtypes and the same bits, so the brace-off input, and every sample after it, is unchanged."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from protocol_runner.archive.units import open_unit
from protocol_runner.steps import trial

from .conftest import run_dry


def test_brace_off_trials_take_the_twin_recording_from_memory_bit_for_bit_as_stored(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    kept: dict[str, tuple[Any, Any]] = {}
    taken: list[str] = []
    keep, read = trial._keep_brace_on, trial._read_brace_on

    def spy_keep(ctx: Any, step: Any, rec: Any) -> None:
        keep(ctx, step, rec)
        kept[step.id] = (step, trial._kept_brace_on[(str(ctx.units_dir), step.id)])

    def spy_read(ctx: Any, step: Any) -> Any:
        if (str(ctx.units_dir), step.twin) in trial._kept_brace_on:
            taken.append(step.twin)
        return read(ctx, step)

    monkeypatch.setattr(trial, "_keep_brace_on", spy_keep)
    monkeypatch.setattr(trial, "_read_brace_on", spy_read)
    session = tmp_path / "s"
    run_dry(session)

    assert kept and sorted(taken) == sorted(kept)  # every twin came from memory, and was let go
    assert not [key for key in trial._kept_brace_on if key[0] == str(session / "units")]
    for step_id, (step, memory) in kept.items():
        with open_unit(session / "units", step_id) as f:
            stored = trial.brace_on_in_unit(f, step, ["knee_flexion"])
        for name in ("time_s", "angle_deg", "command_time_s", "command_deg"):
            # the shared time base once, the joints' angles and commands one array each
            a, b = (
                v if isinstance(v, tuple) else (v,) for v in (getattr(memory, name), getattr(stored, name))
            )
            for x, y in zip(a, b, strict=True):
                assert x.dtype == y.dtype and x.shape == y.shape and x.tobytes() == y.tobytes(), name
