"""Units written on one background thread while the next step runs (issue 20).

The runner hands each finished step's unit to `UnitWriter.submit` and goes on with the next step; one
thread writes the units in order (`archive.units.write_unit`: the file closed, fsynced, renamed, the
directory fsynced) and the main thread journals each one once it is on disk (`collect`, `flush`): a unit is
still journaled as complete only after its file is complete, and only the main thread touches the journal.
The queue is bounded (`MAX_PENDING` units waiting): a step that outruns the disk waits for it instead of
holding every trial's data in memory.

What reads units waits for them: a step reading an earlier unit (`StepContext.unit`) waits for that unit
(`wait_for`); the journal's list of complete units as steps see it, and consolidation, wait for all of them
(`flush`); the analysis workers are handed a configuration once its units are on disk (`ticket`).

A unit submitted with `after` (a comparison run while the analyses it read are still finishing: their
units were complete on disk, not yet journaled) is written at once but journaled only once every unit it
names is journaled (`held` until then): the journal never lists a unit before the units it was made from,
so a crash or stop meanwhile leaves it unjournaled, and a resume redoes it after them.

Failures: the first error of a write (a full disk, a bug in a step's fill) stops the writer: later units are
not attempted (their steps are redone on resume) and the error is raised on the main thread at its next
`submit`, `collect` or `flush`, after every unit written before it has been journaled, so nothing written
is lost and the runner stops the session through its usual paths (DiskFull: exit 130, resumable). A crash
or kill leaves what `write_unit` always leaves: complete units, perhaps an unjournaled one (redone on
resume) or a `.partial` file (removed and redone).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import h5py

from ..archive.units import UnitRecord, write_unit
from ..steps.context import StepContext
from .journal import Journal

MAX_PENDING = 4
"""Units waiting to be written at most (each holds a step's recording in memory)."""

ABANDON_WAIT_S = 30.0
"""How long `abandon` waits for the unit being written to be finished (it is never cut off mid-file)."""


@dataclass(frozen=True)
class _Job:
    step_id: str
    fill: Callable[[h5py.File], None]
    final: bool
    after: tuple[str, ...] = ()


_Written = tuple[UnitRecord, bool, tuple[str, ...]]  # a unit on disk, whether final, what it waits for


class UnitWriter:
    """Writes units on one background thread; the caller's thread journals them (see the module doc)."""

    def __init__(self, units_dir: Path, journal: Journal) -> None:
        self.units_dir = units_dir
        self.journal = journal
        self._jobs: queue.Queue[_Job | None] = queue.Queue(maxsize=MAX_PENDING)
        self._lock = threading.Lock()
        self._done = threading.Condition(self._lock)  # notified as each job is finished (or skipped)
        self._n_submitted = 0
        self._n_finished = 0
        self._index: dict[str, int] = {}  # step id -> its job's number
        self._written: list[_Written] = []  # on disk, not yet journaled (in order)
        self._held: list[_Written] = []  # on disk, waiting for the units they name to be journaled
        self._error: BaseException | None = None
        self._raised = False
        self._abandoned = False
        self._thread: threading.Thread | None = None

    # ------------------------------------------------------------------------------ the main thread

    def submit(
        self,
        step_id: str,
        fill: Callable[[h5py.File], None],
        *,
        final: bool = True,
        after: Sequence[str] = (),
    ) -> None:
        """Queue a unit (waits while MAX_PENDING are queued), to be journaled once written and once the
        units `after` names are journaled. Raises an earlier write's error first."""
        self.collect()
        if self._thread is None:
            self._thread = threading.Thread(target=self._work, name="unit-writer", daemon=True)
            self._thread.start()
        self._jobs.put(_Job(step_id, fill, final, tuple(after)))
        with self._lock:
            self._index[step_id] = self._n_submitted
            self._n_submitted += 1

    def wait_for(self, step_id: str) -> None:
        """Wait until the unit of `step_id` (if it was submitted here) is written, then `collect`."""
        with self._done:
            index = self._index.get(step_id)
            while index is not None and self._n_finished <= index and self._thread is not None:
                self._done.wait()
        self.collect()

    def ticket(self) -> Callable[[], bool]:
        """A test that is True once every unit submitted so far is on disk (False after a write error)."""
        with self._lock:
            mark = self._n_submitted

        def written() -> bool:
            with self._lock:
                return self._error is None and self._n_finished >= mark

        return written

    @property
    def held(self) -> tuple[str, ...]:
        """The units written but not journaled because a unit they name is not journaled yet."""
        return tuple(record.step_id for record, _, _ in self._held)

    def collect(self) -> None:
        """Journal the units written so far (those held, once what they wait for is journaled); then raise
        the writer's error, if it stopped on one."""
        with self._lock:
            written, self._written = self._written, []
            error = self._error
        self._journal_all(written)
        if error is not None and not self._raised:
            self._raised = True
            raise error

    def flush(self) -> None:
        """Wait until every submitted unit is written (or the writer stopped on an error), then `collect`."""
        if self._thread is not None:
            self._jobs.join()
        self.collect()

    def close(self) -> None:
        """Flush and end the thread. An error already raised is not raised again."""
        try:
            self.flush()
        finally:
            self._stop_thread(timeout_s=None)

    def abandon(self) -> None:
        """Stop at once (a second Ctrl-C): drop the queued units (their steps are redone on resume), let
        the one being written finish (a file is never cut off by us), journal what is on disk."""
        self._abandoned = True
        while True:
            try:
                self._jobs.get_nowait()
            except queue.Empty:
                break
            self._jobs.task_done()
        self._stop_thread(timeout_s=ABANDON_WAIT_S)
        with self._lock:
            written, self._written = self._written, []
        self._journal_all(written)

    def _journal_all(self, written: list[_Written]) -> None:
        """Journal the held units whose units are journaled now, then `written`, in order (a unit waiting for
        one not journaled yet is held); if the journal fails (a full disk), the rest wait for the next try."""
        pending, self._held = [*self._held, *written], []
        for k, (record, final, after) in enumerate(pending):
            if any(step_id not in self.journal.units for step_id in after):
                self._held.append((record, final, after))
                continue
            try:
                self.journal.unit_done(record, final=final)
            except BaseException:
                with self._lock:
                    self._written[:0] = pending[k:]
                raise

    def _stop_thread(self, *, timeout_s: float | None) -> None:
        thread, self._thread = self._thread, None
        if thread is None:
            return
        try:
            self._jobs.put(None, timeout=timeout_s)
        except queue.Full:
            return
        thread.join(timeout_s)

    # ------------------------------------------------------------------------------ the writer thread

    def _work(self) -> None:
        while True:
            job = self._jobs.get()
            try:
                if job is None:
                    return
                if self._error is not None or self._abandoned:
                    continue  # stopped: later units are not attempted
                try:
                    record = write_unit(self.units_dir, job.step_id, job.fill)
                except BaseException as exc:  # surfaced on the main thread by collect
                    with self._lock:
                        self._error = exc
                    continue
                with self._lock:
                    self._written.append((record, job.final, job.after))
            finally:
                with self._done:
                    if job is not None:
                        self._n_finished += 1
                    self._done.notify_all()
                self._jobs.task_done()


def written_in_this_run(path: Path, started_ns: int) -> bool:
    """Whether the unit file at `path` exists and was written since `started_ns` (`time.time_ns()`): by this
    run, not left by an earlier one that stopped before journaling it (its file's time is older; a file
    system's coarser clock only makes a new file look older, never an old one newer)."""
    try:
        return path.stat().st_mtime_ns >= started_ns
    except OSError:
        return False


class WrittenJournalView:
    """The journal as steps read it (`StepContext.journal`): a step's unit is written and journaled before
    the journal is asked about it (only that unit is waited for), every submitted unit before the list of
    complete units is walked."""

    def __init__(self, journal: Journal, writer: UnitWriter) -> None:
        self._journal = journal
        self._writer = writer

    @property
    def units(self) -> Mapping[str, object]:
        return _WrittenUnits(self._journal, self._writer)


class _WrittenUnits(Mapping[str, object]):
    def __init__(self, journal: Journal, writer: UnitWriter) -> None:
        self._journal = journal
        self._writer = writer

    def __contains__(self, step_id: object) -> bool:
        if not isinstance(step_id, str):
            return False
        self._writer.wait_for(step_id)  # not the units queued after it (a check waits for its own "before")
        return step_id in self._journal.units

    def __getitem__(self, step_id: str) -> object:
        self._writer.wait_for(step_id)
        return self._journal.units[step_id]

    def __iter__(self) -> Iterator[str]:
        self._writer.flush()
        return iter(dict(self._journal.units))

    def __len__(self) -> int:
        self._writer.flush()
        return len(self._journal.units)


@dataclass
class WritingStepContext(StepContext):
    """A `StepContext` whose `unit` first waits for the units still being written."""

    writer: UnitWriter | None = None

    def unit(self, step_id: str) -> h5py.File:
        if self.writer is not None:
            self.writer.wait_for(step_id)
        return super().unit(step_id)
