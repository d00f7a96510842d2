"""The background unit writer (issue 20): units are written on one thread while the next step runs, in
order, from a bounded queue; a unit is journaled only once its file is complete (closed, fsynced, renamed);
what reads units waits for them; a write error surfaces on the main thread after everything written
before it is journaled, and nothing after it is attempted."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.units import unit_is_complete, unit_path
from protocol_runner.session.journal import Journal
from protocol_runner.session.unit_writer import (
    MAX_PENDING,
    UnitWriter,
    WritingStepContext,
    WrittenJournalView,
    written_in_this_run,
)


def filler(value: float, gate: threading.Event | None = None, started: threading.Event | None = None):  # type: ignore[no-untyped-def]
    def fill(f: h5py.File) -> None:
        if started is not None:
            started.set()
        if gate is not None:
            assert gate.wait(10.0)
        f.create_dataset("x", data=np.full(1000, value))

    return fill


def make(tmp_path: Path) -> tuple[UnitWriter, Journal, Path]:
    units = tmp_path / "units"
    journal = Journal(tmp_path / "journal.jsonl")
    return UnitWriter(units, journal), journal, units


def test_a_unit_is_journaled_only_once_its_file_is_complete_and_submit_does_not_wait(tmp_path: Path) -> None:
    writer, journal, units = make(tmp_path)
    gate, started = threading.Event(), threading.Event()
    t0 = time.monotonic()
    writer.submit("trial:k01:on:1", filler(1.0, gate, started))
    assert time.monotonic() - t0 < 5.0  # the main thread went on while the unit is being written
    assert started.wait(10.0)
    writer.collect()
    assert "trial:k01:on:1" not in journal.units  # being written: not complete, not journaled
    assert not unit_path(units, "trial:k01:on:1").exists()  # only the .partial file exists meanwhile
    assert (units / "trial__k01__on__1.h5.partial").exists()
    gate.set()
    writer.flush()
    record = journal.units["trial:k01:on:1"]
    assert unit_is_complete(units, record)
    assert Journal(tmp_path / "journal.jsonl").units["trial:k01:on:1"] == record  # fsynced to the file
    writer.close()


def test_units_are_written_and_journaled_in_order(tmp_path: Path) -> None:
    writer, journal, units = make(tmp_path)
    ids = [f"trial:k01:on:{k}" for k in range(1, 8)]
    for k, step_id in enumerate(ids):
        writer.submit(step_id, filler(float(k)))
    writer.close()
    assert list(journal.units) == ids
    for k, step_id in enumerate(ids):
        with h5py.File(unit_path(units, step_id)) as f:
            assert f["x"][0] == float(k)


def test_the_queue_is_bounded(tmp_path: Path) -> None:
    writer, _, _ = make(tmp_path)
    gate, started = threading.Event(), threading.Event()
    writer.submit("s:0", filler(0.0, gate, started))
    assert started.wait(10.0)  # the writer holds s:0; MAX_PENDING more fit in the queue
    for k in range(MAX_PENDING):
        writer.submit(f"s:{k + 1}", filler(0.0))
    blocked = threading.Thread(target=writer.submit, args=("s:last", filler(0.0)))
    blocked.start()
    blocked.join(0.3)
    assert blocked.is_alive()  # one more waits for room: memory stays bounded
    gate.set()
    blocked.join(10.0)
    assert not blocked.is_alive()
    writer.close()


def test_a_write_error_surfaces_on_the_main_thread_after_the_units_before_it_are_journaled(
    tmp_path: Path,
) -> None:
    writer, journal, units = make(tmp_path)

    def broken(f: h5py.File) -> None:
        raise ValueError("a bug in a fill")

    writer.submit("s:1", filler(1.0))
    writer.submit("s:2", filler(2.0))
    writer.submit("s:3", broken)
    writer.submit("s:4", filler(4.0))  # submitted before the error was known
    with pytest.raises(ValueError, match="a bug in a fill"):
        writer.flush()
    assert list(journal.units) == ["s:1", "s:2"]  # nothing written is lost
    assert not unit_path(units, "s:4").exists()  # nothing after the error is attempted
    assert not list(units.glob("*.partial"))
    writer.close()  # the error is not raised twice
    assert list(journal.units) == ["s:1", "s:2"]


def test_the_error_also_surfaces_at_the_next_submit(tmp_path: Path) -> None:
    writer, journal, _ = make(tmp_path)

    def broken(f: h5py.File) -> None:
        raise OSError("I/O error")

    writer.submit("s:1", broken)
    deadline = time.monotonic() + 10.0
    with pytest.raises(OSError, match="I/O error"):
        while time.monotonic() < deadline:
            writer.submit("s:next", filler(0.0))
            time.sleep(0.01)
    assert "s:next" not in journal.units
    writer.close()


def test_readers_wait_for_the_units_being_written(tmp_path: Path) -> None:
    writer, journal, units = make(tmp_path)
    view = WrittenJournalView(journal, writer)
    gate = threading.Event()
    writer.submit("calibration:a:before", filler(3.0, gate))
    threading.Timer(0.2, gate.set).start()
    assert "calibration:a:before" in view.units  # the journal as steps see it: waited for the write
    ctx = WritingStepContext(
        loaded=None,  # type: ignore[arg-type]
        plan=None,  # type: ignore[arg-type]
        bench=None,  # type: ignore[arg-type]
        operator=None,  # type: ignore[arg-type]
        units_dir=units,
        journal=view,
        stop_requested=lambda: False,
        processing=None,  # type: ignore[arg-type]
        writer=writer,
    )
    gate2 = threading.Event()
    writer.submit("trial:k01:on:1", filler(5.0, gate2))
    threading.Timer(0.2, gate2.set).start()
    with ctx.unit("trial:k01:on:1") as f:  # a brace-off trial reading its brace-on twin
        assert f["x"][0] == 5.0
    writer.close()


def test_abandon_drops_the_queue_but_finishes_the_unit_being_written(tmp_path: Path) -> None:
    writer, journal, units = make(tmp_path)
    gate, started = threading.Event(), threading.Event()
    writer.submit("s:1", filler(1.0, gate, started))
    assert started.wait(10.0)
    writer.submit("s:2", filler(2.0))

    def open_once_abandoning() -> None:  # s:1 finishes only after the stop is asked for, however slow
        while not writer._abandoned:
            time.sleep(0.001)
        gate.set()

    threading.Thread(target=open_once_abandoning, daemon=True).start()
    writer.abandon()
    assert list(journal.units) == ["s:1"] and unit_is_complete(units, journal.units["s:1"])
    assert not unit_path(units, "s:2").exists()


def test_a_ticket_passes_once_the_units_submitted_before_it_are_on_disk(tmp_path: Path) -> None:
    writer, _, units = make(tmp_path)
    gate = threading.Event()
    before = writer.ticket()
    assert before()  # nothing submitted yet
    writer.submit("trial:k01:off:3", filler(1.0, gate))
    ticket = writer.ticket()  # what the configuration's processing waits for
    writer.submit("cal:a:after", filler(2.0))
    assert not ticket()
    gate.set()
    deadline = time.monotonic() + 10.0
    while not ticket() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert ticket() and unit_path(units, "trial:k01:off:3").exists()  # on disk when it passes
    writer.close()


def test_a_ticket_never_passes_after_a_write_error(tmp_path: Path) -> None:
    writer, _, _ = make(tmp_path)

    def broken(f: h5py.File) -> None:
        raise OSError("I/O error")

    writer.submit("s:1", broken)
    ticket = writer.ticket()
    with pytest.raises(OSError):
        writer.flush()
    assert not ticket()  # the analysis of units that were never written is not started
    writer.close()


def test_wait_for_waits_for_that_unit_only(tmp_path: Path) -> None:
    writer, journal, units = make(tmp_path)
    gate = threading.Event()
    writer.submit("trial:k01:on:1", filler(1.0))
    writer.submit("trial:k01:on:2", filler(2.0, gate))  # still being written
    writer.wait_for("trial:k01:on:1")
    assert "trial:k01:on:1" in journal.units and "trial:k01:on:2" not in journal.units
    writer.wait_for("trial:k01:on:9")  # not submitted here: nothing to wait for
    gate.set()
    writer.close()
    assert unit_is_complete(units, journal.units["trial:k01:on:2"])


def test_asking_the_journal_about_a_unit_waits_for_that_unit_not_for_those_queued_after_it(
    tmp_path: Path,
) -> None:
    """A calibration check after a set asks whether the check before it is complete: it must not wait for
    the set's brace-off trials still being written (issue 20: the main loop stalled there)."""
    writer, journal, _ = make(tmp_path)
    view = WrittenJournalView(journal, writer)
    gate = threading.Event()
    writer.submit("calibration:a:before", filler(1.0))
    writer.submit("trial:k01:off:3", filler(2.0, gate))  # held until the gate opens
    assert "calibration:a:before" in view.units  # answered while the trial's unit is still being written
    assert view.units["calibration:a:before"] is journal.units["calibration:a:before"]
    assert "trial:k01:off:3" not in journal.units and not gate.is_set()
    threading.Timer(0.2, gate.set).start()
    assert sorted(view.units) == ["calibration:a:before", "trial:k01:off:3"]  # walking waits for all
    assert len(view.units) == 2
    writer.close()


def test_a_unit_made_from_unjournaled_units_is_journaled_after_them(tmp_path: Path) -> None:
    """A comparison run while the analysis it read was still finishing: its unit is written at once but
    journaled only after that analysis's unit; units that wait for nothing are journaled meanwhile."""
    writer, journal, units = make(tmp_path)
    writer.submit("compare:x", filler(1.0), after=["process:k01"])
    writer.submit("trial:k02:on:1", filler(2.0))
    writer.flush()
    assert unit_path(units, "compare:x").is_file()  # on disk (written, renamed into place) ...
    assert "compare:x" not in journal.units  # ... not journaled: what it read is not
    assert writer.held == ("compare:x",)
    assert "trial:k02:on:1" in journal.units
    writer.submit("process:k01", filler(3.0))
    writer.flush()
    writer.collect()
    assert writer.held == ()
    order = list(journal.units)
    assert order.index("process:k01") < order.index("compare:x")
    reread = Journal(tmp_path / "journal.jsonl")  # as a resume reads it
    assert list(reread.units) == order
    writer.close()


def test_a_held_unit_stays_unjournaled_when_what_it_waits_for_never_comes(tmp_path: Path) -> None:
    """A stop before the analysis ends: the comparison's file is on disk but not journaled, so a resume
    redoes it (after the analysis it reads)."""
    writer, _journal, units = make(tmp_path)
    writer.submit("compare:x", filler(1.0), after=["process:k01"])
    writer.close()
    assert unit_path(units, "compare:x").is_file()
    assert "compare:x" not in Journal(tmp_path / "journal.jsonl").units


def test_a_unit_file_counts_as_this_runs_only_when_written_since_it_started(tmp_path: Path) -> None:
    path = tmp_path / "process__k01.h5"
    started = time.time_ns()
    assert not written_in_this_run(path, started)  # not there
    path.write_bytes(b"unit")
    assert written_in_this_run(path, started)
    stale = started - 60_000_000_000  # left by a run a minute earlier
    os.utime(path, ns=(stale, stale))
    assert not written_in_this_run(path, started)
