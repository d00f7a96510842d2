"""The report's configurations read ahead from the archive's draft (`session/read_ahead.py`): the session's
report is the one read wholly from its archive, and a configuration read ahead is used only while its
archive group is the one it was read from."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.report import load as load_module
from protocol_runner.report.render import generate_report
from protocol_runner.session.assembly import ArchiveDraft
from protocol_runner.session.journal import Journal
from protocol_runner.session.read_ahead import ReadAhead

from .conftest import ONLY, run_dry


def _without_time(html: str) -> list[str]:
    return [line for line in html.splitlines() if "generated-utc" not in line]


def test_the_session_report_reads_ahead_and_equals_the_report_read_from_the_archive(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    session = tmp_path / "s"
    given: list[list[str]] = []
    real = load_module.load_report_data

    def spying(path, *, workers=None, verify=True, known=None):  # type: ignore[no-untyped-def]
        given.append(sorted(known or {}))
        return real(path, workers=workers, verify=verify, known=known)

    monkeypatch.setattr(load_module, "load_report_data", spying)
    assert run_dry(session, only=[11, 12]) == 0
    # the analyses of the configuration run first ended while the session waited: read ahead, not again
    assert len(given) == 1 and len(given[0]) == 1 and given[0][0] in ("config_11", "config_12")
    again = generate_report(session / "archive.h5", tmp_path / "again.html", workers=1)
    assert _without_time(again.read_text()) == _without_time((session / "report.html").read_text())
    with pytest.raises(ValueError):  # what was read ahead is never mixed with a checked read
        real(session / "archive.h5", known={"config_11": object()})  # type: ignore[dict-item]


def test_a_configuration_read_before_a_unit_that_holds_it_is_read_again(tmp_path: Path) -> None:
    session = tmp_path / "s"
    assert run_dry(session) == 0
    journal = Journal(session / "journal.jsonl")
    fit = journal.units.pop("fit:k12")
    journal.units["fit:k12"] = fit  # its fit journaled last
    ahead = ArchiveDraft(session, journal)
    ahead.update()
    reading = ReadAhead(expand(load_protocol(find_protocol("knee_phase1.yaml")), only=ONLY), ahead)
    reading.update()
    assert list(reading.known()) == ["config_12"]
    read = reading.read["config_12"]
    reading.read["config_12"] = dataclasses.replace(read, records=read.records[:-1])  # read before its fit
    assert reading.known() == {}
    reading.read["config_12"] = dataclasses.replace(read, attrs={**read.attrs, "status": "partial"})
    assert reading.known() == {}  # consolidation wrote other attributes than those it was read with
    journal.units.pop("fit:k12")
    assert reading.known() == {}  # a unit it was read with is gone
