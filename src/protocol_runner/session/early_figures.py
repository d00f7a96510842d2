"""A configuration's report figures, drawn by the analysis worker as soon as its analyses are written.

The configuration is read from its own units (viewed as consolidation merges them, without copying, and
read by the report's own reader), its figures drawn and stored in the figure cache beside the archive
(`report/figure_cache.py`). The report at the end then only assembles: it takes a stored figure when it
was drawn from exactly the data it reads from the archive, and draws anything else itself. The
configuration read goes back to the session with the worker's result (`UnitsRead`), for the report's
data (`read_ahead.py`). Drawing ahead is an optimisation only: any failure here leaves the figure to the
report.
"""

from __future__ import annotations

import contextlib
import functools
import os
import posixpath
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py

from ..archive.attrs import ATTRIBUTES
from ..archive.checksums import MARKER_ATTR
from ..archive.paths import configuration_name
from ..archive.units import unit_path
from ..protocol.plan import FitStep, Plan, ProcessStep
from ..protocol.step_ids import step_id

if TYPE_CHECKING:
    from ..report.model import Configuration


def configuration_step_ids(plan: Plan, key: object) -> list[str]:
    """The ids of configuration `key`'s steps (the only ones that write into its group), in plan order."""
    return [s.id for s in plan.steps if getattr(s, "configuration", None) == key]


def configuration_unit_files(plan: Plan, units_dir: Path, key: int) -> list[Path]:
    """The written units of configuration `key`'s steps, in plan order."""
    files = [unit_path(units_dir, step) for step in configuration_step_ids(plan, key)]
    return [f for f in files if f.is_file()]


def key_to_draw_ahead(plan: Plan, step_ids: tuple[str, ...]) -> int | None:
    """The configuration whose figures to draw once the analysis steps `step_ids` are written: the one whose
    analyses they end (its fit, or its processing when it has no fit), unless it is the plan's last
    configuration with analyses (`final_configuration`): the session waits for that one before it
    consolidates, so its worker hands its units back at once, and draws its figures in a task of their own
    while the session consolidates (`runner.Runner._finish`)."""
    last = plan.step(step_ids[-1]) if step_ids else None
    if not isinstance(last, (ProcessStep, FitStep)):
        return None
    key = last.configuration
    return key if last.id == ending_step_id(plan, key) and key != final_configuration(plan) else None


def ending_step_id(plan: Plan, key: int) -> str:
    """The id of the step that ends configuration `key`'s analyses: its fit, or its processing without one."""
    fit = step_id("fit", key=key)
    return fit if fit in plan._index else step_id("process", key=key)


def final_configuration(plan: Plan) -> int | None:
    """The plan's last configuration with analyses (a processing step), if any."""
    keys = [s.configuration for s in plan.steps if isinstance(s, ProcessStep)]
    return keys[-1] if keys else None


def analysed_in_this_run(plan: Plan, key: int, submitted: set[str]) -> bool:
    """Whether configuration `key`'s analyses ended in this run (its last analysis step, the fit or else the
    processing, was among the steps `submitted` to the workers)."""
    return ending_step_id(plan, key) in submitted


class UnitsView:
    """The units' groups at one archive path read as consolidation would merge them, without copying:
    a member is the last unit's dataset, or the view of every unit's group of that name; attributes are
    merged in unit order (a later unit's value wins), the units' own attributes left out. Enough of
    `h5py.Group` for the report's configuration reader (`in`, `[]` with relative paths, iteration in
    HDF5's name order, `attrs`). What is asked of a unit is asked once (`_Layer`): a path is then looked
    up in dictionaries, not asked of HDF5 unit by unit. A unit holding a soft or external link or a
    named datatype (which this program's units never do) is refused with `ValueError`."""

    def __init__(self, layers: list[h5py.Group]) -> None:
        self._layers = [_Layer(group) for group in layers]
        self._path = ""  # the view's path in each of its layers ("" is the layers themselves)

    @classmethod
    def _at(cls, layers: list[_Layer], path: str) -> UnitsView:
        view = cls.__new__(cls)
        view._layers, view._path = layers, path
        return view

    @property
    def name(self) -> str:
        base = str(self._layers[0].group.name)
        return posixpath.join(base, self._path) if self._path else base

    def _full(self, path: str) -> str:
        if path.startswith("/"):
            raise ValueError(f"the units' view is read by relative paths, not {path!r}")
        parts = [part for part in path.split("/") if part not in ("", ".")]
        return "/".join([self._path, *parts] if self._path else parts)

    def __contains__(self, path: str) -> bool:
        full = self._full(path)
        return any(full in layer for layer in self._layers)

    def __getitem__(self, path: str) -> h5py.Dataset | UnitsView:
        full = self._full(path)
        found = [(layer, got) for layer in self._layers if (got := layer.get(full)) is not None]
        if not found:
            raise KeyError(path)
        if isinstance(found[-1][1], h5py.Dataset):
            return found[-1][1]
        return UnitsView._at([layer for layer, got in found if isinstance(got, h5py.Group)], full)

    def __iter__(self) -> Iterator[str]:
        names = {name for layer in self._layers for name in layer.members(self._path)}
        return iter(sorted(names))  # HDF5's name order

    def keys(self) -> list[str]:
        return list(self)

    def items(self) -> list[tuple[str, h5py.Dataset | UnitsView]]:
        return [(name, self[name]) for name in self]

    @functools.cached_property
    def attrs(self) -> MergedAttrs:
        return MergedAttrs([layer.get(self._path) for layer in self._layers])


class _Layer:
    """One unit's group (a layer of a `UnitsView`) and what has been asked of it: each object opened once,
    a group's members listed once (one listing of its links inside the HDF5 library), so that a path is
    then looked up in dictionaries instead of asked of HDF5 unit by unit."""

    def __init__(self, group: h5py.Group) -> None:
        self.group = group
        self._readonly = group.file.mode == "r"
        self._objects: dict[str, h5py.Group | h5py.Dataset | None] = {"": group}  # None: absent
        self._members: dict[str, set[str]] = {}  # a group's path ("" the layer's own) -> its names

    def get(self, path: str) -> h5py.Group | h5py.Dataset | None:
        """The group or dataset at `path` (None when the layer holds none)."""
        if path not in self._objects:
            parent, _, name = path.rpartition("/")
            self._objects[path] = self._open(path) if name in self.members(parent) else None
        return self._objects[path]

    def members(self, path: str) -> set[str]:
        """The names in the group at `path` (none when there is no group there)."""
        if path not in self._members:
            found = self.get(path)
            self._members[path] = self._listed(found) if isinstance(found, h5py.Group) else set()
        return self._members[path]

    def __contains__(self, path: str) -> bool:
        parent, _, name = path.rpartition("/")
        return name in self.members(parent)

    def _open(self, path: str) -> h5py.Group | h5py.Dataset:
        found = h5py.h5o.open(self.group.id, path.encode())
        if isinstance(found, h5py.h5g.GroupID):
            return h5py.Group(found)
        if isinstance(found, h5py.h5d.DatasetID):
            return h5py.Dataset(found, readonly=self._readonly)
        raise ValueError(f"{self._where(path)} is neither a group nor a dataset")

    def _listed(self, group: h5py.Group) -> set[str]:
        links: list[tuple[bytes, int]] = []
        group.id.links.iterate(lambda name, info: links.append((name, info.type)), info=True)
        if any(kind != h5py.h5l.TYPE_HARD for _, kind in links):  # (not raised inside HDF5's iteration)
            raise ValueError(f"{self._where(str(group.name))} holds a soft or external link")
        return {name.decode() for name, _ in links}

    def _where(self, path: str) -> str:
        return f"{self.group.file.filename}: {posixpath.join(str(self.group.name), path)}"


class MergedAttrs(Mapping[str, Any]):
    """The attributes of a `UnitsView`: its groups' merged in order (a later group's value wins), the units'
    own left out, in HDF5's name order. Each value is read when first asked for, from the group it comes
    from, and kept."""

    def __init__(self, groups: list[h5py.Group]) -> None:
        source: dict[str, h5py.AttributeManager] = {}
        for group in groups:
            attrs = group.attrs
            names: list[bytes] = []
            h5py.h5a.iterate(group.id, names.append)  # their names, listed inside HDF5 (sorted below)
            for key in names:
                source[key.decode()] = attrs
        self._source = {key: source[key] for key in sorted(source) if key not in _NOT_MERGED}
        self._values: dict[str, Any] = {}

    def __getitem__(self, key: str) -> Any:
        if key not in self._values:
            self._values[key] = self._source[key][key]
        return self._values[key]

    def __contains__(self, key: object) -> bool:
        return key in self._source

    def __iter__(self) -> Iterator[str]:
        return iter(self._source)

    def __len__(self) -> int:
        return len(self._source)


_NOT_MERGED = frozenset((*ATTRIBUTES["unit"], MARKER_ATTR))


FileIdentity = tuple[int, int, int, int]  # device, inode, size, modification time (ns)


def file_identity(st: os.stat_result) -> FileIdentity:
    """Which file a unit's path names: a unit rewritten (written anew, then renamed) is another file."""
    return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)


@dataclass(frozen=True)
class UnitsRead:
    """A configuration read from its units by the analysis worker that ended its analyses, handed to the
    session (`read_ahead.ReadAhead.offer`) so that the session does not read it again."""

    configuration: Configuration  # read by the report's reader from the units' merge (`UnitsView`)
    attrs: dict[str, Any]  # the group's own attributes merged from the units, as read
    files: tuple[tuple[str, FileIdentity], ...]  # the unit files read (names in the units folder), in order


def read_units(plan: Plan, units_dir: Path, key: int) -> UnitsRead | None:
    """Configuration `key` read from its units as consolidation will merge them (None if it cannot be)."""
    name = configuration_name(key)
    with contextlib.suppress(Exception), contextlib.ExitStack() as files:  # an optimisation only
        units = [
            files.enter_context(h5py.File(f, "r")) for f in configuration_unit_files(plan, units_dir, key)
        ]
        read = _read_merged(units, name)
        if read is None:
            return None
        opened = tuple((Path(u.filename).name, file_identity(os.fstat(u.id.get_vfd_handle()))) for u in units)
        return UnitsRead(*read, opened)
    return None


def _read_merged(units: list[h5py.File], name: str) -> tuple[Configuration, dict[str, Any]] | None:
    """Configuration `name` and its group's attributes read from the units' merge (`UnitsView`), if they
    hold it. The view and the HDF5 objects it opened are let go on return, before the files are closed
    (closing a file with objects still open costs HDF5 more)."""
    from ..report.load_configuration import read_configuration

    merged = UnitsView(units)  # the configuration as consolidation will merge it, read in place
    if f"configurations/{name}" not in merged:
        return None
    group = merged[f"configurations/{name}"]
    return read_configuration(name, group), dict(group.attrs)


def draw_ahead(plan: Plan, units_dir: Path, key: int, archive: Path) -> UnitsRead | None:
    """Draw configuration `key`'s figures into the figure cache of `archive`; the configuration as read from
    its units for them (None if it could not be read: nothing is drawn then)."""
    from ..report.figure_cache import cache_dir_of, save  # here: only the workers draw (matplotlib)
    from ..report.figures import draw_configuration

    read = read_units(plan, units_dir, key)
    if read is None:
        return None
    with contextlib.suppress(Exception):  # an optimisation: the report draws whatever is not stored
        images = draw_configuration(read.configuration)
        if images is not None:
            save(cache_dir_of(archive), read.configuration, images)
    return read
