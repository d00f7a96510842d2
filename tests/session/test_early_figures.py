"""Figures drawn ahead: the analysis worker draws a configuration's figures once its analyses are written;
the report only assembles them, and is the same without them."""

from __future__ import annotations

import contextlib
import re
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.archive.attrs import UNIT_COMPLETE, UNIT_STEP_ID
from protocol_runner.archive.checksums import MARKER_ATTR
from protocol_runner.archive.consolidate import merge_units
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.report.figure_cache import cache_dir_of, lookup
from protocol_runner.report.figures import draw_configuration
from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import generate_report
from protocol_runner.session.early_figures import (
    UnitsView,
    analysed_in_this_run,
    draw_ahead,
    final_configuration,
    key_to_draw_ahead,
)
from protocol_runner.session.setup import load_session_protocol, read_session_info


def _without_time(html: str) -> str:
    return re.sub(r'id="generated-utc"[^<]*', "", html)


def test_figures_are_drawn_after_a_configurations_last_analysis_except_the_plans_last() -> None:
    plan = expand(load_protocol(find_protocol("knee_phase1.yaml")), only=[4, 5])
    assert key_to_draw_ahead(plan, ("process:k04", "fit:k04")) == 4
    assert key_to_draw_ahead(plan, ("fit:k04",)) == 4  # resumed: the processing was done before
    assert key_to_draw_ahead(plan, ("process:k04",)) is None  # its fit is still to come
    # the last configuration: its worker hands its units back at once (the session waits for them before
    # it consolidates), and its figures are drawn in a task of their own meanwhile
    assert key_to_draw_ahead(plan, ("process:k05", "fit:k05")) is None
    assert key_to_draw_ahead(plan, ()) is None
    assert final_configuration(plan) == 5
    assert analysed_in_this_run(plan, 5, {"process:k05", "fit:k05"})
    assert analysed_in_this_run(plan, 5, {"fit:k05"})  # resumed after its processing
    assert not analysed_in_this_run(plan, 5, {"process:k04", "fit:k04"})  # done in an earlier run
    assert not analysed_in_this_run(plan, 5, {"process:k05"})  # its fit is what ends its analyses


def test_figures_drawn_from_the_units_are_those_of_the_archive(
    reference_archive: Path, tmp_path: Path
) -> None:
    session = reference_archive.parent
    _, plan, _ = load_session_protocol(session, read_session_info(session), force=False)
    (key,) = {s.configuration for s in plan.steps if s.kind == "fit"}  # type: ignore[attr-defined]
    cfg = load_report_data(reference_archive).configuration(key)
    assert cfg is not None
    # the session's one (so its last) configuration: drawn on a worker while the session consolidated
    assert final_configuration(plan) == key
    assert lookup(cache_dir_of(reference_archive), cfg) == draw_configuration(cfg)
    elsewhere = tmp_path / "archive.h5"  # the figure folder goes beside it, not into the shared session
    read = draw_ahead(plan, session / "units", key, elsewhere)
    assert read is not None
    stored = lookup(cache_dir_of(elsewhere), cfg)  # drawn from the units, the same data as the archive's
    assert stored is not None
    assert stored == draw_configuration(cfg)


def test_the_sessions_report_is_the_report_of_its_archive(reference_archive: Path, tmp_path: Path) -> None:
    """--report on a copy of the archive (checksums checked, no stored figures) gives the same HTML."""
    alone = tmp_path / "archive.h5"
    shutil.copy(reference_archive, alone)
    assert not cache_dir_of(alone).exists()
    regenerated = generate_report(alone, tmp_path / "report.html").read_text(encoding="utf-8")
    session_report = (reference_archive.parent / "report.html").read_text(encoding="utf-8")
    regenerated = regenerated.replace(str(alone), str(reference_archive))  # the report names its archive
    assert _without_time(regenerated) == _without_time(session_report)


def _write_units(folder: Path) -> list[Path]:
    """Three units adding to one configuration as a trial, a second trial and its processing do: the
    group's attributes repeated with a later value, a dataset and an array attribute rewritten by a later
    unit, groups of one name in several units, an empty group, the units' own attributes at every level."""
    paths = [folder / f"unit{i}.h5" for i in range(3)]
    for i, path in enumerate(paths):
        with h5py.File(path, "w") as unit:
            unit.attrs[UNIT_STEP_ID] = f"step{i}"
            unit.attrs[UNIT_COMPLETE] = True
            unit.attrs[MARKER_ATTR] = "sha256"
            cfg = unit.create_group("configurations/config_01")
            cfg.attrs["key"] = 1
            cfg.attrs["status"] = ["partial", "partial", "complete"][i]
            cfg.attrs[f"only_{i}"] = float(i)
            cfg.attrs["range_deg"] = np.array([i, i + 1.0])
            if i < 2:  # trials 1, then 2 and 10 (after 1, before 2 in HDF5's name order)
                for number in ("1",) if i == 0 else ("2", "10"):
                    raw = cfg.create_group(f"trials/{number}/brace_on")
                    raw.attrs["tick_lateness_p99_s"] = 0.001 * (i + 1)
                    raw.create_dataset("angle_deg", data=np.arange(5.0) + i)
                cfg.create_dataset("energy_loss_j", data=[9.0])
                cfg.create_group("notes") if i == 0 else None
            else:
                for number in ("1", "2"):
                    processed = cfg.create_group(f"trials/{number}/processed")
                    processed.attrs["subtraction"] = "equal_angle"
                    processed.create_dataset("angle_deg", data=np.arange(3, dtype=np.int16))
                cfg.create_dataset("energy_loss_j", data=[2.0, 3.0])  # replaces the trials' value
                cfg.create_group("fits/bouc_wen").attrs["rmse_nm"] = 0.5
    return paths


def _assert_merged(view: UnitsView, want: h5py.Group) -> None:
    """The view answers as the merged group `want` does, member by member and attribute by attribute."""
    assert list(view) == list(want) == view.keys(), want.name  # HDF5's name order
    assert list(view.attrs) == list(want.attrs), want.name
    for key, value in want.attrs.items():
        assert key in view.attrs and type(view.attrs[key]) is type(value), (want.name, key)
        assert np.array_equal(view.attrs[key], value), (want.name, key)
    for (name, got), member in zip(view.items(), want.values(), strict=True):
        assert name in view
        if isinstance(member, h5py.Dataset):
            assert isinstance(got, h5py.Dataset) and got.dtype == member.dtype, member.name
            assert got[()].tolist() == member[()].tolist(), member.name
        else:
            assert isinstance(got, UnitsView) and got.name == member.name
            _assert_merged(got, member)


def test_the_units_view_reads_what_consolidation_writes(tmp_path: Path) -> None:
    """The units read through the view give, at every level, the members and attributes of the archive
    consolidation merges from them: a later unit's dataset and attribute win, groups of one name are one,
    the units' own attributes are not there, names come in HDF5's order."""
    paths = _write_units(tmp_path)
    merged = tmp_path / "merged.h5"
    with h5py.File(merged, "w") as out:
        merge_units(out, paths)
    with contextlib.ExitStack() as stack:
        out = stack.enter_context(h5py.File(merged, "r"))
        view = UnitsView([stack.enter_context(h5py.File(p, "r")) for p in paths])
        _assert_merged(view, out)
        cfg = view["configurations/config_01"]
        assert isinstance(cfg, UnitsView)
        assert cfg.attrs["status"] == "complete" and list(cfg.attrs["range_deg"]) == [2.0, 3.0]
        assert not {UNIT_STEP_ID, UNIT_COMPLETE, MARKER_ATTR} & {*view.attrs, *cfg.attrs}
        assert list(cfg) == ["energy_loss_j", "fits", "notes", "trials"]
        assert list(cfg["trials"]) == ["1", "10", "2"]
        assert list(cfg["trials/1"]) == ["brace_on", "processed"]  # one group from two units
        assert cfg["energy_loss_j"][()].tolist() == [2.0, 3.0]
        assert "trials/2/processed/angle_deg" in cfg and "./trials//10" in cfg
        assert "trials/3" not in cfg and "energy_loss_j/x" not in cfg and "fits/spring" not in cfg
        with pytest.raises(KeyError):
            cfg["trials/3/processed"]


def test_a_unit_holding_links_is_not_read_through_the_view(tmp_path: Path) -> None:
    """The view lists each unit's groups as this program writes them (groups and datasets only); a file
    holding a soft link is refused, and left to the report read from the archive."""
    (path,) = _write_units(tmp_path)[:1]
    with h5py.File(path, "a") as unit:
        unit["configurations/config_01/trials/alias"] = h5py.SoftLink("/configurations/config_01/trials/1")
    with h5py.File(path, "r") as unit:
        view = UnitsView([unit])
        assert "configurations/config_01/energy_loss_j" in view
        with pytest.raises(ValueError, match="link"):
            "configurations/config_01/trials/1" in view  # noqa: B015
