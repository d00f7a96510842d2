"""Configuration figures drawn ahead: used only when drawn from exactly the data the report reads."""

from __future__ import annotations

import dataclasses
import shutil
from pathlib import Path

import numpy as np
import pytest

from protocol_runner.report.figure_cache import (
    FIGURE_FIELDS,
    cache_dir_of,
    fingerprint,
    lookup,
    save,
)
from protocol_runner.report.figures import configuration_tasks, draw_configuration, render_figures
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import Configuration, ReportData

FAKE = "data:image/png;base64,c3RvcmVk"  # not a figure any drawing makes: shows that the store was used


def _stored_fakes(small_archive: Path, tmp_path: Path) -> tuple[Path, ReportData, Configuration, list[str]]:
    """A copy of the archive whose figure store holds FAKE for each of configuration 5's figures: the copy,
    its report data, the configuration and its figure ids."""
    archive = tmp_path / "archive.h5"
    shutil.copy(small_archive, archive)
    data = load_report_data(archive)
    cfg = data.configuration(5)
    assert cfg is not None
    ids = [task_id for task_id, _ in configuration_tasks(cfg)]
    save(cache_dir_of(archive), cfg, dict.fromkeys(ids, FAKE))
    return archive, data, cfg, ids


def _with(data: ReportData, cfg: Configuration) -> ReportData:
    configs = tuple(cfg if c.key == cfg.key else c for c in data.configurations)
    return dataclasses.replace(data, configurations=configs)


def test_every_figure_field_is_in_the_fingerprint(small_archive: Path) -> None:
    cfg = load_report_data(small_archive).configuration(5)
    assert cfg is not None and cfg.bouc_wen is not None
    base = fingerprint(cfg)
    energy = cfg.energy_loss_j.copy()
    energy[0] += 1e-9  # one cycle's energy, in its last digits
    changed = {
        "key": dataclasses.replace(cfg, key=cfg.key + 100),
        "trials": dataclasses.replace(cfg, trials=cfg.trials[:-1]),
        "energy_loss_j": dataclasses.replace(cfg, energy_loss_j=energy),
        "energy_cycle_trial": dataclasses.replace(
            cfg, energy_cycle_trial=cfg.energy_cycle_trial[::-1].copy()
        ),
        "bouc_wen": dataclasses.replace(cfg, bouc_wen=None),
        "element_fit": dataclasses.replace(cfg, element_fit=None),
    }
    assert set(changed) == set(FIGURE_FIELDS)
    for name, other in changed.items():
        assert fingerprint(other) != base, name


def test_fields_outside_the_fingerprint_do_not_change_the_figures(small_archive: Path) -> None:
    data = load_report_data(small_archive)
    cfg, other = data.configuration(5), data.configuration(6)
    assert cfg is not None and other is not None
    # every field the fingerprint leaves out, taken from another configuration
    mixed = dataclasses.replace(other, **{name: getattr(cfg, name) for name in FIGURE_FIELDS}, name=cfg.name)
    assert fingerprint(mixed) == fingerprint(cfg)
    assert draw_configuration(mixed) == draw_configuration(cfg)


def test_the_report_takes_stored_figures_drawn_from_the_same_data(
    small_archive: Path, tmp_path: Path
) -> None:
    _, data, _, ids = _stored_fakes(small_archive, tmp_path)
    figures = render_figures(data, workers=1)
    assert all(figures.get(i) == FAKE for i in ids)
    # the other configurations' figures were drawn, and document order is kept
    assert sum(uri == FAKE for uri in figures.images.values()) == len(ids)
    assert list(figures.images) == [i for i in render_figures(data, workers=1).images]


@pytest.mark.parametrize("change", ["data", "damaged file"])
def test_a_stale_or_damaged_store_is_drawn_again(small_archive: Path, tmp_path: Path, change: str) -> None:
    archive, data, cfg, ids = _stored_fakes(small_archive, tmp_path)
    if change == "data":  # e.g. --reprocess changed the energies after the figures were drawn
        energy = np.asarray(cfg.energy_loss_j) * 1.5
        data = _with(data, dataclasses.replace(cfg, energy_loss_j=energy))
    else:
        path = cache_dir_of(archive) / f"{cfg.name}.json"
        path.write_bytes(path.read_bytes()[:100])
    assert lookup(cache_dir_of(archive), data.configuration(5)) is None  # type: ignore[arg-type]
    figures = render_figures(data, workers=1)
    assert FAKE not in figures.images.values()
    fresh = data.configuration(5)
    assert fresh is not None
    assert {i: figures.get(i) for i in ids} == draw_configuration(fresh)
