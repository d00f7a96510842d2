"""Read an archive (docs/archive.md) into a `ReportData`, with clear errors for anything that is not one.

`load_report_data(path)` accepts `archive.h5` or the session directory holding it. A corrupt, truncated
or foreign file, or a dataset outside the layout's bounds or not matching its checksum, raises `protocol_runner.errors.InvalidInput` naming the file and what is wrong; an
archive of an unfinished session (root `status` other than "complete") loads normally and the report
marks it incomplete.

The session-wide groups are read by `load_session.py`, each configuration by `load_configuration.py`,
with the small attribute readers of `h5read.py`; the checks are `archive/verify.py`'s.
"""

from __future__ import annotations

import os
from pathlib import Path

import h5py

from protocol_runner.archive.verify import (
    Checker,
    check_root,
    corrupt,
    require_hdf5,
    resolve_archive,
)
from protocol_runner.errors import InvalidInput
from protocol_runner.report.declared import declared_count
from protocol_runner.report.h5read import attr_str, scalar_str
from protocol_runner.report.load_configuration import read_configuration
from protocol_runner.report.load_session import (
    read_calibration,
    read_comparisons,
    read_references,
    read_session,
)
from protocol_runner.report.model import Configuration, JointsTotal, ReportData
from protocol_runner.report.parallel import map_in_processes


def load_report_data(
    path: Path,
    *,
    workers: int | None = None,
    verify: bool = True,
) -> ReportData:
    """Read the archive at `path` (a file, or a session directory holding `archive.h5`).

    `workers` > 1 reads the configurations on that many worker processes (decompressing a full
    campaign's trials is most of the load time); None picks 2 for large archives on a multi-core machine.
    Raises `InvalidInput` when the file is missing, not HDF5, truncated or corrupt, not a protocol-runner
    archive (no root attribute `protocol_sha256`), lacks the `/configurations` group, or holds a dataset
    outside the layout's bounds or a dataset or attribute whose checksum does not match (archive/verify.py):
    every dataset and attribute is checked before the report uses anything. `verify=False` reads the datasets without checking them
    (neither checksums nor bounds): only for an archive this process has just consolidated from units
    whose sha256 it checked against the journal (the session's own report): every byte of it is then
    known to be what protocol-runner wrote, within its bounds and matching its checksums.
    """
    archive = resolve_archive(Path(path))
    require_hdf5(archive)
    try:
        with h5py.File(archive, "r") as h5:
            names = check_root(h5, archive)
        # the file is closed before the workers start: HDF5 handles must not be shared with a forked process
        configurations, totals = _load_configurations(archive, names, workers, verify)
        with h5py.File(archive, "r") as h5:
            if verify:  # the root's and every other group's attributes and datasets (configurations: above)
                checker = Checker.of(h5, archive)
                checker.check_tree(h5, skip=("configurations",))
                checker.check_attributes(h5["configurations"])
            return _read(h5, archive, configurations, totals)
    except InvalidInput:
        raise
    except (OSError, KeyError, ValueError, TypeError, RuntimeError) as exc:
        raise corrupt(archive, exc) from exc


Loaded = tuple[list[Configuration], JointsTotal | None]
"""A configuration group as read: one `Configuration` per joint, and the energy of all its joints together."""


def _load_chunk(archive: Path, names: list[str], verify: bool = True) -> list[Loaded]:
    with h5py.File(archive, "r") as h5:
        checker = Checker.of(h5, archive) if verify else None
        joints = attr_str(h5.attrs, "joint")
        out = []
        for name in names:
            if checker is not None:  # all of it, read or not: damage is named
                checker.check_tree(h5["configurations"][name])
            out.append(read_configuration(name, h5["configurations"][name], joints))
        return out


def _load_configurations(
    archive: Path, names: list[str], workers: int | None, verify: bool
) -> tuple[tuple[Configuration, ...], tuple[JointsTotal, ...]]:
    """Every configuration group's joints, in key order (and channel order within a key), and the totals."""
    if workers is None:
        workers = 2 if len(names) >= 12 and (os.cpu_count() or 1) >= 2 else 1
    loaded: list[Loaded] | None = None
    if workers > 1 and len(names) >= 2:
        loaded = map_in_processes(
            _load_one, [(archive, name, verify) for name in names], workers, chunksize=2
        )
    if loaded is None:
        loaded = _load_chunk(archive, names, verify)
    loaded.sort(key=lambda item: item[0][0].key if item[0] else item[1].key if item[1] else 0)
    configurations = tuple(cfg for configs, _ in loaded for cfg in configs)
    totals = tuple(total for _, total in loaded if total is not None)
    return configurations, totals


def _load_one(item: tuple[Path, str, bool]) -> Loaded:
    archive, name, verify = item
    return _load_chunk(archive, [name], verify)[0]


def _read(
    h5: h5py.File,
    archive: Path,
    configurations: tuple[Configuration, ...],
    totals: tuple[JointsTotal, ...],
) -> ReportData:
    session = read_session(h5, archive)
    calibration = read_calibration(h5)
    comparisons = read_comparisons(h5)
    references = read_references(h5)
    protocol_text = scalar_str(h5["protocol"]) if "protocol" in h5 else ""
    notes: list[str] = []
    if not comparisons:
        declared = declared_count(protocol_text, ("report", "comparisons"))
        notes.append(
            f"The protocol declares {declared} comparison{'s' if declared != 1 else ''}, none made yet in "
            f"this session (status {session.status}): the report shows no cross-configuration figures."
            if declared
            else "The protocol declares no comparisons (its report section's comparisons): the report "
            "shows no cross-configuration figures."
        )
    return ReportData(
        session=session,
        configurations=configurations,
        calibration=calibration,
        comparisons=comparisons,
        references=references,
        protocol_text=protocol_text,
        notes=tuple(notes),
        joints=session.joints or tuple(dict.fromkeys(cfg.joint for cfg in configurations)),
        totals=totals,
    )
