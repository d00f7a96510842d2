"""A configuration's report figures, drawn by the analysis worker as soon as its analyses are written.

The configuration is read from its own units (viewed as consolidation merges them, without copying, and
read by the report's own reader), its figures drawn and stored in the figure cache beside the archive
(`report/figure_cache.py`). The report at the end then only assembles: it takes a stored figure when it
was drawn from exactly the data it reads from the archive, and draws anything else itself. Drawing ahead
is an optimisation only: any failure here leaves the figure to the report.
"""

from __future__ import annotations

import contextlib
import functools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import h5py

from ..archive.attrs import ATTRIBUTES
from ..archive.checksums import MARKER_ATTR
from ..archive.paths import configuration_name
from ..archive.units import unit_path
from ..protocol.plan import FitStep, Plan, ProcessStep
from ..protocol.step_ids import step_id


def configuration_unit_files(plan: Plan, units_dir: Path, key: int) -> list[Path]:
    """The written units of configuration `key`'s steps, in plan order."""
    files = [unit_path(units_dir, s.id) for s in plan.steps if getattr(s, "configuration", None) == key]
    return [f for f in files if f.is_file()]


def key_to_draw_ahead(plan: Plan, step_ids: tuple[str, ...]) -> int | None:
    """The configuration whose figures to draw once the analysis steps `step_ids` are written: the one whose
    analyses they end (its fit, or its processing when it has no fit), unless it is the plan's last
    configuration with analyses: the session waits for that one before its report anyway, and the report
    process draws it without a worker loading matplotlib (a one-configuration run draws nothing ahead)."""
    last = plan.step(step_ids[-1]) if step_ids else None
    if not isinstance(last, (ProcessStep, FitStep)):
        return None
    key = last.configuration
    ends = isinstance(last, FitStep) or step_id("fit", key=key) not in plan._index
    final = [s.configuration for s in plan.steps if isinstance(s, ProcessStep)][-1:] == [key]
    return key if ends and not final else None


class UnitsView:
    """The units' groups at one archive path read as consolidation would merge them, without copying:
    a member is the last unit's dataset, or the view of every unit's group of that name; attributes are
    merged in unit order (a later unit's value wins), the units' own attributes left out. Enough of
    `h5py.Group` for the report's configuration reader (`in`, `[]` with paths, iteration, `attrs`)."""

    def __init__(self, layers: list[h5py.Group]) -> None:
        self._layers = layers

    @property
    def name(self) -> str:
        return str(self._layers[0].name)

    def __contains__(self, path: str) -> bool:
        return any(path in layer for layer in self._layers)

    def __getitem__(self, path: str) -> h5py.Dataset | UnitsView:
        found = [layer[path] for layer in self._layers if path in layer]
        if not found:
            raise KeyError(path)
        if isinstance(found[-1], h5py.Dataset):
            return found[-1]
        return UnitsView([g for g in found if isinstance(g, h5py.Group)])

    def __iter__(self) -> Iterator[str]:
        return iter(sorted({name for layer in self._layers for name in layer}))  # HDF5's name order

    def keys(self) -> list[str]:
        return list(self)

    def items(self) -> list[tuple[str, h5py.Dataset | UnitsView]]:
        return [(name, self[name]) for name in self]

    @functools.cached_property
    def attrs(self) -> dict[str, Any]:
        names = [list(layer.attrs) for layer in self._layers]
        order = dict.fromkeys(k for layer_names in names for k in layer_names if k not in _NOT_MERGED)
        merged: dict[str, Any] = {}
        for layer, layer_names in zip(reversed(self._layers), reversed(names), strict=True):
            for key in layer_names:  # each value read once, from the last unit that sets it
                if key in order and key not in merged:
                    merged[key] = layer.attrs[key]
        return {key: merged[key] for key in sorted(order)}  # HDF5 lists attributes by name


_NOT_MERGED = frozenset((*ATTRIBUTES["unit"], MARKER_ATTR))


def draw_ahead(plan: Plan, units_dir: Path, key: int, archive: Path) -> bool:
    """Draw configuration `key`'s figures into the figure cache of `archive`; whether they were stored."""
    from ..report.figure_cache import cache_dir_of, save  # here: only the workers draw (matplotlib)
    from ..report.figures import draw_configuration
    from ..report.load_configuration import read_configuration

    name = configuration_name(key)
    with contextlib.suppress(Exception):  # an optimisation: the report draws whatever is not stored
        with contextlib.ExitStack() as files:
            units = [
                files.enter_context(h5py.File(f, "r")) for f in configuration_unit_files(plan, units_dir, key)
            ]
            merged = UnitsView(units)  # the configuration as consolidation will merge it, read in place
            if f"configurations/{name}" not in merged:
                return False
            cfg = read_configuration(name, merged[f"configurations/{name}"])
        images = draw_configuration(cfg)
        if images is not None:
            save(cache_dir_of(archive), cfg, images)
            return True
    return False
