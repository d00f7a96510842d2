"""The report's configurations read ahead (`session/read_ahead.py`), from the analysis workers' reads or the
archive's draft: the session's report is the one read wholly from its archive, a configuration read ahead
is the report reader's configuration of the archive's group, field by field, and it is used only while
that group is the one it was read from."""

from __future__ import annotations

import dataclasses
import math
import os
import shutil
from pathlib import Path
from typing import Any

import h5py
import numpy as np
import pytest

from protocol_runner.archive.consolidate import merge_units
from protocol_runner.archive.paths import configuration_name
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import Plan, expand
from protocol_runner.report import load as load_module
from protocol_runner.report import load_configuration
from protocol_runner.report.figure_cache import fingerprint
from protocol_runner.report.load_configuration import read_configuration
from protocol_runner.report.model import Configuration
from protocol_runner.report.render import generate_report
from protocol_runner.session.assembly import ArchiveDraft
from protocol_runner.session.early_figures import configuration_unit_files, file_identity, read_units
from protocol_runner.session.journal import Journal
from protocol_runner.session.read_ahead import ReadAhead

from .conftest import ONLY, run_dry


def _without_time(html: str) -> list[str]:
    return [line for line in html.splitlines() if "generated-utc" not in line]


def _assert_same(got: Any, want: Any, where: str) -> None:
    """`got` is `want` field by field: the same types, arrays of the same dtype, shape, bits and
    writability, numbers of the same bits (NaN included)."""
    assert type(got) is type(want), where
    if dataclasses.is_dataclass(want):
        for field in dataclasses.fields(want):
            _assert_same(getattr(got, field.name), getattr(want, field.name), f"{where}.{field.name}")
    elif isinstance(want, np.ndarray):
        assert (got.dtype, got.shape) == (want.dtype, want.shape), where
        assert np.array_equal(got, want, equal_nan=want.dtype.kind == "f"), where
        assert got.tobytes() == want.tobytes(), where
        assert got.flags.writeable == want.flags.writeable, where
    elif isinstance(want, tuple):
        assert len(got) == len(want), where
        for i, (g, w) in enumerate(zip(got, want, strict=True)):
            _assert_same(g, w, f"{where}[{i}]")
    elif isinstance(want, float) and math.isnan(want):
        assert math.isnan(got), where
    else:
        assert got == want, where


def _archived(archive: Path, name: str) -> Configuration:
    with h5py.File(archive, "r") as f:
        return read_configuration(name, f["configurations"][name])


def _knee_plan(only: list[int]) -> Plan:
    return expand(load_protocol(find_protocol("knee_phase1.yaml")), only=only)


def _taking(session: Path, journal: Journal, key: int) -> ReadAhead:
    """A read-ahead of `session` offered the configuration read from its units, with no draft to read."""
    reading = ReadAhead(_knee_plan(ONLY), ArchiveDraft(session, journal))
    read = read_units(reading.plan, session / "units", key)
    assert read is not None
    reading.offer(read)
    return reading


def test_a_configuration_read_from_its_units_is_the_one_read_from_their_merge(
    reference_archive: Path, tmp_path: Path
) -> None:
    """A dry run's configuration read from its units (through `UnitsView`) is, field by field, the one the
    report's reader gives on the group consolidation merges from the same units, with that group's
    attributes (same names in the same order, same types and bits) and the unit files read, in order."""
    session = reference_archive.parent
    (key,) = ONLY
    name = configuration_name(key)
    plan = _knee_plan(ONLY)
    files = configuration_unit_files(plan, session / "units", key)
    read = read_units(plan, session / "units", key)
    assert read is not None
    with h5py.File(tmp_path / "merged.h5", "w") as out:
        merge_units(out, files)
    with h5py.File(tmp_path / "merged.h5", "r") as out:
        group = out["configurations"][name]
        want = read_configuration(name, group)
        attrs = {key: group.attrs[key] for key in group.attrs}
    _assert_same(read.configuration, want, name)
    assert fingerprint(read.configuration) == fingerprint(want)
    assert list(read.attrs) == list(attrs) and len(attrs) > 10
    for attr, value in attrs.items():
        got = read.attrs[attr]
        if isinstance(value, np.ndarray) and value.dtype.kind == "O":  # strings: compared as strings
            assert (type(got), got.dtype, got.tolist()) == (np.ndarray, value.dtype, value.tolist()), attr
        else:
            _assert_same(got, value, attr)
    assert read.files == tuple((f.name, file_identity(f.stat())) for f in files)
    assert len(files) >= 3  # trials, processing and fit at least


def test_the_session_report_reads_ahead_and_equals_the_report_read_from_the_archive(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The configuration drawn ahead is read by the worker that ended its analyses and not again by the
    session; what the report is handed is, field by field, what the report's reader gives on the
    consolidated archive, and the report is the one read wholly from the archive."""
    session = tmp_path / "s"
    given: list[dict[str, Configuration]] = []
    real = load_module.load_report_data

    def spying(path, *, workers=None, verify=True, known=None):  # type: ignore[no-untyped-def]
        given.append(dict(known or {}))
        return real(path, workers=workers, verify=verify, known=known)

    in_session: list[str] = []
    reader = load_configuration.read_configuration

    def reading(name: str, grp: h5py.Group) -> Configuration:  # the session's reads (the workers' are apart)
        in_session.append(name)
        return reader(name, grp)

    monkeypatch.setattr(load_module, "load_report_data", spying)
    monkeypatch.setattr(load_configuration, "read_configuration", reading)
    assert run_dry(session, only=[11, 12]) == 0
    drawn_ahead = "config_11"  # the plan's last configuration (12) is drawn by the report, not ahead
    assert len(given) == 1 and drawn_ahead in given[0]
    assert drawn_ahead not in in_session  # the worker's read was taken
    for name, cfg in given[0].items():  # the last one too, when read from the draft while waiting
        _assert_same(cfg, _archived(session / "archive.h5", name), name)
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


def test_the_attributes_consolidation_writes_win_over_the_units(reference_archive: Path) -> None:
    """A worker's read is taken with the group's attributes read again from the units' attributes with
    consolidation's over them: a status, planned trials or key the units say otherwise is not the archive's."""
    session = reference_archive.parent
    (key,) = ONLY
    name = configuration_name(key)
    reading = _taking(session, Journal(session / "journal.jsonl"), key)
    read = reading.offered[name]
    units_say = {"status": "partial", "n_trials": 99, "key": 98}
    reading.offered[name] = dataclasses.replace(
        read,
        configuration=dataclasses.replace(read.configuration, status="partial", n_trials_planned=99, key=98),
        attrs={**read.attrs, **units_say},
    )
    reading.update()
    known = reading.known()
    assert list(known) == [name]
    archived = _archived(reference_archive, name)
    assert (archived.status, archived.key) == ("complete", key)
    _assert_same(known[name], archived, name)


def test_a_workers_read_of_units_that_are_not_those_archived_is_not_taken(
    reference_archive: Path, tmp_path: Path
) -> None:
    """Taken only if the units read are those consolidation merges, in its order, and the very files
    journaled; otherwise the configuration is read from the draft, as without the workers' reads."""
    session = tmp_path / "s"
    shutil.copytree(reference_archive.parent, session)
    (key,) = ONLY
    name = configuration_name(key)
    journal = Journal(session / "journal.jsonl")
    assert list(_taking(session, journal, key).known()) == []  # nothing taken before `update`
    reading = _taking(session, journal, key)
    reading.update()
    assert list(reading.known()) == [name]  # as it is

    first = next(r for r in journal.units.values() if r.step_id.startswith("trial"))
    journal.units[first.step_id] = journal.units.pop(first.step_id)  # its trial merged last, not first
    reading = _taking(session, journal, key)
    reading.update()
    assert reading.known() == {}

    journal = Journal(session / "journal.jsonl")
    reading = _taking(session, journal, key)
    unit = session / "units" / first.file
    shutil.copy(unit, unit.with_suffix(".new"))
    os.replace(unit.with_suffix(".new"), unit)  # the same bytes, but a file written after the read
    reading.update()
    assert reading.known() == {}

    ahead = ArchiveDraft(session, journal)  # with a draft to read from instead
    ahead.update()
    reading = ReadAhead(_knee_plan(ONLY), ahead)
    stale = read_units(reading.plan, session / "units", key)
    assert stale is not None
    shutil.copy(unit, unit.with_suffix(".new"))
    os.replace(unit.with_suffix(".new"), unit)
    reading.offer(stale)
    reading.update()
    known = reading.known()
    assert list(known) == [name]
    _assert_same(known[name], _archived(reference_archive, name), name)


def test_only_a_configurations_steps_write_into_its_group(reference_archive: Path) -> None:
    """What the read-ahead relies on to take a worker's read: the units holding `configurations/<name>`
    are those of the configuration's own steps."""
    session = reference_archive.parent
    plan = _knee_plan(ONLY)
    journal = Journal(session / "journal.jsonl")
    holding = 0
    for record in journal.units.values():
        with h5py.File(session / "units" / record.file, "r") as unit:
            held = set(unit.get("configurations", ()))
        key = getattr(plan.step(record.step_id), "configuration", None)
        assert held <= ({configuration_name(key)} if key is not None else set()), record.step_id
        holding += bool(held)
    assert holding >= 3  # trials, processing and fit at least
