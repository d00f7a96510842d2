"""Is this file an intact protocol-runner archive? Clear answers for foreign, damaged or hostile files.

- `Checker`: each dataset's layout (archive/layout.py) before it is read, then its values against its
  recorded checksum, and each object's attributes against theirs (the report checks everything with it).
- `validate_archive`: an HDF5 file with the archive's root marker and `/configurations`, every dataset
  passing `Checker` (`--reprocess` and `--export-mat` call it before they read).
- `verify_path`: `run-protocol --verify SESSION_DIR|ARCHIVE.h5`, listing every damaged dataset.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import h5py

from ..errors import InvalidInput, short
from .attrs import UNIT_COMPLETE, UNIT_STEP_ID
from .checksums import (
    attributes_marked,
    digest_of_stored,
    is_marked,
    recorded_attribute_digests,
    recorded_digest,
    stored_attribute_digests,
)
from .layout import check_layout, element_cap

ROOT_MARKER = "protocol_sha256"
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_READ_ERRORS = (OSError, KeyError, ValueError, TypeError, RuntimeError, UnicodeDecodeError)


def corrupt(archive: Path, exc: BaseException) -> InvalidInput:
    return InvalidInput(
        f"{archive} is truncated or corrupt; it cannot be read as an archive ({short(exc)}). "
        "Re-consolidate the session or use a backup copy."
    )


def resolve_archive(path: Path) -> Path:
    """`path` itself, or the `archive.h5` of the session directory `path`."""
    if path.is_dir():
        candidate = path / "archive.h5"
        if not candidate.is_file():
            raise InvalidInput(f"{path} is a directory without an archive.h5 (is it a session directory?).")
        return candidate
    if not path.exists():
        raise InvalidInput(f"{path} does not exist.")
    return path


def require_hdf5(path: Path) -> None:
    """The HDF5 signature sits at offset 0, or 512, 1024, 2048, ... when the file has a user block."""
    try:
        with path.open("rb") as fh:
            offset = 0
            while True:
                fh.seek(offset)
                head = fh.read(8)
                if len(head) < 8:
                    break
                if head == HDF5_SIGNATURE:
                    return
                offset = 512 if offset == 0 else offset * 2
    except OSError as exc:
        raise InvalidInput(f"{path} cannot be read: {exc.strerror or exc}.") from exc
    raise InvalidInput(f"{path} is not an HDF5 file (no HDF5 signature); expected a protocol-runner archive.")


def check_root(h5: h5py.File, archive: Path) -> list[str]:
    """The names of the archive's configuration groups, after checking its root."""
    if ROOT_MARKER not in h5.attrs:
        raise InvalidInput(
            f"{archive} is not a protocol-runner archive: missing root attribute {ROOT_MARKER}."
        )
    if "configurations" not in h5 or not isinstance(h5["configurations"], h5py.Group):
        raise InvalidInput(f"{archive} is incomplete: missing group /configurations (see docs/archive.md).")
    return [name for name, grp in h5["configurations"].items() if isinstance(grp, h5py.Group)]


def validate_archive(path: Path) -> Path:
    """Check that `path` (a file or session directory) is a readable, intact protocol-runner archive:
    its root, then every dataset's layout and checksum (`Checker`). Returns the archive's path; raises
    `InvalidInput` naming the file, and the dataset, at the first problem."""
    archive = resolve_archive(Path(path))
    require_hdf5(archive)
    try:
        with h5py.File(archive, "r") as h5:
            check_root(h5, archive)
            Checker.of(h5, archive).check_tree(h5)
    except InvalidInput:
        raise
    except _READ_ERRORS as exc:
        raise corrupt(archive, exc) from exc
    return archive


@dataclass
class Checker:
    """Checks datasets of one open file (layout, then checksum) and every object's attributes. `strict`
    (the file declares dataset checksums) makes a dataset without one an error, `attrs_strict` an attribute
    without one; otherwise they are counted as unsummed. Without `digests` only the layout is checked."""

    label: str
    cap: int
    strict: bool
    checked: int = 0
    unsummed: int = 0
    digests: bool = True
    attrs_strict: bool = False
    attrs_checked: int = 0
    attrs_unsummed: int = 0

    @classmethod
    def of(cls, f: h5py.File, label: object, *, digests: bool = True) -> Checker:
        return cls(
            str(label), element_cap(f), is_marked(f), digests=digests, attrs_strict=attributes_marked(f)
        )

    def check_attributes(self, obj: h5py.HLObject) -> None:
        """Raise `InvalidInput` naming the file, the object and the attribute unless every attribute of
        `obj` matches the checksum recorded when it was written (and none recorded has been removed)."""
        if not self.digests:
            return
        where = f"{self.label}: {obj.name}"
        try:
            recorded = recorded_attribute_digests(obj)
        except (ValueError, *_READ_ERRORS) as exc:
            raise InvalidInput(f"{where}: its attribute checksums cannot be read ({short(exc)})") from None
        try:
            stored = stored_attribute_digests(obj)
        except _READ_ERRORS as exc:
            raise InvalidInput(
                f"{where}: its attributes are damaged: they cannot be read ({short(exc)})"
            ) from None
        for name, actual in stored.items():
            expected = None if recorded is None else recorded.get(name)
            if expected is None:
                if self.attrs_strict:
                    raise InvalidInput(
                        f"{where}@{name} has no checksum although the file declares one on every attribute"
                    )
                self.attrs_unsummed += 1
            elif actual != expected:
                raise InvalidInput(
                    f"{where}@{name} is damaged: its value no longer matches the sha256 checksum recorded "
                    "when it was written. Check the file with run-protocol --verify; use a backup copy, or "
                    "re-consolidate the session from its units"
                )
            else:
                self.attrs_checked += 1
        gone = sorted(set(recorded or ()) - set(stored))
        if gone:
            raise InvalidInput(f"{where}@{gone[0]} is missing: it was removed after it was written")

    def check(self, ds: h5py.Dataset) -> None:
        """Raise `InvalidInput` naming the file and the dataset unless it is within bounds and intact
        (its values and its attributes)."""
        where = f"{self.label}: dataset {ds.name}"
        check_layout(ds, self.cap, where)
        if not self.digests:
            return
        recorded = recorded_digest(ds)
        if recorded is None:
            if self.strict:
                raise InvalidInput(f"{where} has no checksum although the file declares one on every dataset")
            self.unsummed += 1
            self.check_attributes(ds)
            return
        try:
            actual = digest_of_stored(ds)
        except _READ_ERRORS as exc:
            raise InvalidInput(f"{where} is damaged: it cannot be read ({short(exc)})") from None
        if actual != recorded:
            raise InvalidInput(
                f"{where} is damaged: its data no longer match the sha256 checksum recorded when it was "
                "written. Check the file with run-protocol --verify; use a backup copy, or re-consolidate "
                "the session from its units"
            )
        self.checked += 1
        self.check_attributes(ds)

    def check_tree(self, group: h5py.Group, skip: tuple[str, ...] = ()) -> None:
        """Check `group`'s attributes and every dataset and group under it (names in `skip`, directly under
        it, excluded)."""
        self.check_attributes(group)
        for name, obj in group.items():
            if name in skip:
                continue
            if isinstance(obj, h5py.Dataset):
                self.check(obj)
            elif isinstance(obj, h5py.Group):
                self.check_tree(obj)

    def problems(self, group: h5py.Group) -> list[str]:
        """Every dataset, and every object's attributes, under `group` (itself included) that fails its
        check, as messages (for --verify)."""
        found: list[str] = []

        def visit(_: str, obj: object) -> None:
            try:
                if isinstance(obj, h5py.Dataset):
                    self.check(obj)
                elif isinstance(obj, h5py.Group):
                    self.check_attributes(obj)
            except InvalidInput as exc:
                found.append(exc.message)

        visit("", group)
        group.visititems(visit)
        return found


@dataclass
class Verdict:
    lines: list[str] = field(default_factory=list)  # one summary per file
    problems: list[str] = field(default_factory=list)


def verify_path(path: Path) -> Verdict:
    """`--verify`: an archive file, or a session directory (its archive.h5 and its units/*.h5)."""
    path = Path(path)
    verdict = Verdict()
    if path.is_file():
        _verify_file(path, verdict)
        return verdict
    if not path.is_dir():
        raise InvalidInput(f"{path}: no such archive or session directory")
    units = sorted((path / "units").glob("*.h5"))
    if not (path / "archive.h5").is_file() and not units:
        raise InvalidInput(f"{path}: neither an archive.h5 nor a session directory with units")
    archive = path / "archive.h5"
    if os.path.lexists(archive):  # _verify_file names one that is not a regular file
        _verify_file(archive, verdict)
    if units:
        each = Verdict()
        datasets = sum(_verify_file(unit, each) for unit in units)
        verdict.problems.extend(each.problems)
        if not each.problems:
            verdict.lines.append(
                f"{path / 'units'}: {len(units)} units, {datasets} datasets, every checksum matches"
            )
    return verdict


def _verify_file(file: Path, verdict: Verdict) -> int:
    """Check `file`, adding its summary or its problems to `verdict`; the number of datasets verified."""
    if not file.is_file():  # a FIFO would block the read forever, a directory has nothing to check
        verdict.problems.append(f"{file}: not a regular file (a directory, a FIFO, a dangling link?)")
        return 0
    try:
        require_hdf5(file)
        with h5py.File(file, "r") as h5:
            if UNIT_STEP_ID in h5.attrs:  # a unit: a fragment of the archive, no root of its own
                if not h5.attrs.get(UNIT_COMPLETE, False):
                    raise InvalidInput(f"{file}: not a complete unit (resume redoes its step)")
            else:
                check_root(h5, file)
            checker = Checker.of(h5, file)
            found = checker.problems(h5)
    except InvalidInput as exc:
        verdict.problems.append(exc.message)
        return 0
    except _READ_ERRORS as exc:
        verdict.problems.append(corrupt(file, exc).message)
        return 0
    verdict.problems.extend(found)
    if checker.unsummed and not checker.checked:
        verdict.problems.append(
            f"{file}: has no checksums (written by a protocol-runner older than --verify); cannot be verified"
        )
    elif not found:
        unsummed = f" ({checker.unsummed} written without one)" if checker.unsummed else ""
        attributes = f" and {checker.attrs_checked} attributes" if checker.attrs_checked else ""
        unsummed_attrs = ""
        if checker.attrs_unsummed:  # written before attribute checksums: its results' attributes unverifiable
            which = (
                f"{checker.attrs_unsummed} of its attributes" if checker.attrs_checked else "its attributes"
            )
            unsummed_attrs = f"; {which} carry no checksum (written before attribute checksums)"
        verdict.lines.append(
            f"{file}: {checker.checked} datasets{attributes}, every checksum matches{unsummed}{unsummed_attrs}"
        )
    return checker.checked
