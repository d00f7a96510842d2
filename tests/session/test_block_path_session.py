"""A whole dry run (configuration 12: calibration checks, brace-on trials, brace-off trials with their
scaling runs, processing, fit, report) gives the same archive, bit for bit, whether the simulated rig sends
tick by tick or in blocks (issue 20): the block path changes the speed, not the data."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest

from protocol_runner.hardware.simulator import SimulatedRig

from .conftest import assert_same_data, run_dry


def test_the_per_tick_loop_gives_the_block_paths_archive(
    tmp_path: Path, reference_archive: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    sends: list[str] = []
    real = SimulatedRig.send_block

    def counted(self: SimulatedRig, *args, **kwargs):  # type: ignore[no-untyped-def]
        sends.append("block")
        return real(self, *args, **kwargs)

    monkeypatch.setattr(SimulatedRig, "send_block", counted)
    monkeypatch.setattr(SimulatedRig, "accepts_scheduled_blocks", property(lambda self: False))
    session = tmp_path / "per-tick"
    assert run_dry(session) == 0
    assert sends == []  # this run went tick by tick
    with h5py.File(reference_archive, "r") as f:  # the reference has every kind of rig step
        assert "calibration" in f and any("scaling" in name for name in _names(f))
    assert_same_data(reference_archive, session / "archive.h5")


def _names(f: h5py.File) -> list[str]:
    names: list[str] = []
    f.visit(names.append)
    return names
