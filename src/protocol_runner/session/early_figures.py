"""A configuration's report figures, drawn by the analysis worker as soon as its analyses are written.

The configuration is read from its own units (merged in memory as consolidation merges them, read by the
report's own reader), its figures drawn and stored in the figure cache beside the archive
(`report/figure_cache.py`). The report at the end then only assembles: it takes a stored figure when it
was drawn from exactly the data it reads from the archive, and draws anything else itself. Drawing ahead
is an optimisation only: any failure here leaves the figure to the report.
"""

from __future__ import annotations

import contextlib
import itertools
import os
from pathlib import Path

import h5py

from ..archive.consolidate import merge_units
from ..archive.paths import configuration_name
from ..archive.units import unit_path
from ..protocol.plan import FitStep, Plan, ProcessStep
from ..protocol.step_ids import step_id

_MEMORY_FILES = itertools.count()


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


def draw_ahead(plan: Plan, units_dir: Path, key: int, archive: Path) -> bool:
    """Draw configuration `key`'s figures into the figure cache of `archive`; whether they were stored."""
    from ..report.figure_cache import cache_dir_of, save  # here: only the workers draw (matplotlib)
    from ..report.figures import draw_configuration
    from ..report.load_configuration import read_configuration

    name = configuration_name(key)
    with contextlib.suppress(Exception):  # an optimisation: the report draws whatever is not stored
        memory = f"units-{os.getpid()}-{next(_MEMORY_FILES)}.h5"
        with h5py.File(memory, "w", driver="core", backing_store=False) as merged:
            merge_units(merged, configuration_unit_files(plan, units_dir, key))
            if f"configurations/{name}" not in merged:
                return False
            cfg = read_configuration(name, merged["configurations"][name])
        images = draw_configuration(cfg)
        if images is not None:
            save(cache_dir_of(archive), cfg, images)
            return True
    return False
