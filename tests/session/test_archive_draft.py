"""The archive drafted while the session waits for its last analyses (`session.assembly.ArchiveDraft`):
the units journaled by then are merged ahead, consolidation at the end adds only the later ones, and the
archive is exactly the one a consolidation from scratch gives; a draft that no longer leads the journal's
units (a unit redone) is left aside."""

from __future__ import annotations

import os
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive import consolidate as consolidate_module
from protocol_runner.report import render as render_module
from protocol_runner.session import assembly
from protocol_runner.session.journal import Journal

from .conftest import archive_contents, assert_same_data, run_dry


def test_the_session_consolidates_onto_its_draft_and_gets_the_archive_from_scratch(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "s"
    calls: list[tuple[int, int]] = []  # (units drafted ahead, units in all)

    def spying(archive: Path, files, meta, ahead=None):  # type: ignore[no-untyped-def]
        scratch = tmp_path / "scratch" / "archive.h5"
        scratch.parent.mkdir(exist_ok=True)
        consolidate_module.consolidate(scratch, files, meta)  # the same units, no draft
        calls.append((len(ahead.files) if ahead is not None and ahead.leads(list(files)) else 0, len(files)))
        return consolidate_module.consolidate(archive, files, meta, ahead)

    drawn_on: list[tuple[int | None, bool]] = []
    real_render = render_module.render_report

    def rendering(data, output, *, generated_utc=None, workers=None, draw=None, predicted=None):  # type: ignore[no-untyped-def]
        drawn_on.append((workers, draw is not None and predicted is not None))
        return real_render(
            data, output, generated_utc=generated_utc, workers=workers, draw=draw, predicted=predicted
        )

    monkeypatch.setattr(assembly, "consolidate", spying)
    monkeypatch.setattr(render_module, "render_report", rendering)
    assert run_dry(session) == 0
    # the report's figures not drawn ahead are drawn on both cores, by the analysis workers (done by then)
    assert drawn_on == [(min(2, os.cpu_count() or 1), (os.cpu_count() or 1) >= 2)]
    assert len(calls) == 1
    drafted, total = calls[0]
    # every trial and calibration unit was merged ahead; only the last analyses were left for the end
    assert 0 < drafted < total
    assert_same_data(tmp_path / "scratch" / "archive.h5", session / "archive.h5")
    extra = (
        archive_contents(session / "archive.h5").keys()
        - archive_contents(tmp_path / "scratch" / "archive.h5").keys()
    )
    assert extra and all(k.startswith("expectations") for k in extra)  # the report's verdicts, added after
    assert not (session / "archive.h5.partial").exists()
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "complete"


def test_a_draft_is_left_aside_once_a_unit_it_holds_is_redone(tmp_path: Path) -> None:
    session = tmp_path / "s"
    assert run_dry(session) == 0
    journal = Journal(session / "journal.jsonl")
    ahead = assembly.ArchiveDraft(session, journal)
    ahead.update()
    records = list(journal.units.values())
    started, files = ahead.lead(records)
    assert started is not None and len(files) == len(records) and started.path.is_file()
    first = records[0]
    journal.units.pop(first.step_id)
    journal.units[first.step_id] = first  # redone: journaled again, now last
    assert ahead.lead(list(journal.units.values())) == (None, [])
    ahead.update()  # drafted afresh, in the journal's new order
    started, files = ahead.lead(list(journal.units.values()))
    assert started is not None and files[-1].name == first.file
