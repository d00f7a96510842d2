"""A comparison may run while the last analyses finish (session/runner.py: as soon as the processing units
it reads are on disk), but the journal lists it only after the units it was made from: a resume never keeps
a comparison whose analyses it redoes."""

from __future__ import annotations

import json
from pathlib import Path

import h5py

from protocol_runner.protocol.step_ids import step_id

from .conftest import run_dry


def test_every_comparison_is_journaled_after_the_processing_it_read(tmp_path: Path) -> None:
    session = tmp_path / "s"
    assert run_dry(session, only=[12, 13]) == 0
    lines = [
        json.loads(line) for line in (session / "journal.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    order = [line["step_id"] for line in lines if line.get("record") == "unit"]
    with h5py.File(session / "archive.h5", "r") as f:
        compared = {name: [int(k) for k in g.attrs["configurations"]] for name, g in f["comparisons"].items()}
    assert compared  # the two configurations make two comparisons
    for name, keys in compared.items():
        at = order.index(f"compare:{name}")
        for key in keys:
            assert order.index(step_id("process", key=key)) < at, (name, key)


def test_the_progress_shows_a_comparison_after_the_processing_it_read(tmp_path: Path) -> None:
    """Its line is held until the processing units are journaled (before, a comparison made while the
    analyses ran was shown before their lines), and the lines are numbered in the order they are shown."""
    import re

    session = tmp_path / "s"
    assert run_dry(session, only=[12, 13]) == 0
    shown = [
        (int(m.group(1)), int(m.group(2)), m.group(3))
        for m in re.finditer(
            r"\[(\d+)/(\d+)\] ([^:\s]+(?::[^:\s]+)*): ", (session / "session.log").read_text()
        )
    ]
    numbers = [n for n, _, _ in shown]
    assert numbers == list(range(1, shown[0][1] + 1))  # every step once, numbered as shown
    order = [step for _, _, step in shown]
    compares = [step for step in order if step.startswith("compare:")]
    assert compares
    with h5py.File(session / "archive.h5", "r") as f:
        for step in compares:
            keys = [int(k) for k in f["comparisons"][step.split(":", 1)[1]].attrs["configurations"]]
            for key in keys:
                assert order.index(step_id("process", key=key)) < order.index(step), (step, order)
