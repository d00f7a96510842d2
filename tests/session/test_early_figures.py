"""Figures drawn ahead: the analysis worker draws a configuration's figures once its analyses are written;
the report only assembles them, and is the same without them."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.report.figure_cache import cache_dir_of, lookup
from protocol_runner.report.figures import draw_configuration
from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import generate_report
from protocol_runner.session.early_figures import draw_ahead, key_to_draw_ahead
from protocol_runner.session.setup import load_session_protocol, read_session_info


def _without_time(html: str) -> str:
    return re.sub(r'id="generated-utc"[^<]*', "", html)


def test_figures_are_drawn_after_a_configurations_last_analysis_except_the_plans_last() -> None:
    plan = expand(load_protocol(find_protocol("knee_phase1.yaml")), only=[4, 5])
    assert key_to_draw_ahead(plan, ("process:k04", "fit:k04")) == 4
    assert key_to_draw_ahead(plan, ("fit:k04",)) == 4  # resumed: the processing was done before
    assert key_to_draw_ahead(plan, ("process:k04",)) is None  # its fit is still to come
    # the last configuration: the session waits for it before the report, which draws it
    assert key_to_draw_ahead(plan, ("process:k05", "fit:k05")) is None
    assert key_to_draw_ahead(plan, ()) is None


def test_figures_drawn_from_the_units_are_those_of_the_archive(
    reference_archive: Path, tmp_path: Path
) -> None:
    session = reference_archive.parent
    assert not cache_dir_of(reference_archive).exists()  # one configuration: nothing drawn ahead
    _, plan, _ = load_session_protocol(session, read_session_info(session), force=False)
    elsewhere = tmp_path / "archive.h5"  # the figure folder goes beside it, not into the shared session
    (key,) = {s.configuration for s in plan.steps if s.kind == "fit"}  # type: ignore[attr-defined]
    read = draw_ahead(plan, session / "units", key, elsewhere)
    assert read is not None
    cfg = load_report_data(reference_archive).configuration(key)
    assert cfg is not None
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


def test_the_units_view_reads_what_consolidation_writes(tmp_path: Path) -> None:
    """Two units adding to one configuration: the view gives the merged archive's members and attributes
    (the later unit's value wins; the units' own attributes are not part of the archive)."""
    import h5py

    from protocol_runner.archive.consolidate import merge_units
    from protocol_runner.session.early_figures import UnitsView

    paths = [tmp_path / "a.h5", tmp_path / "b.h5"]
    for i, path in enumerate(paths):
        with h5py.File(path, "w") as unit:
            unit.attrs["unit_step_id"] = f"step{i}"
            cfg = unit.create_group("configurations/config_01")
            cfg.attrs["key"] = 1
            cfg.attrs["status"] = ["partial", "complete"][i]
            cfg.attrs[f"only_{i}"] = float(i)
            unit.create_dataset(f"configurations/config_01/trials/{i + 1}/processed/angle_deg", data=[i, i])
            unit.create_dataset("configurations/config_01/energy_loss_j", data=[float(i)])
    merged = tmp_path / "merged.h5"
    with h5py.File(merged, "w") as out:
        merge_units(out, paths)
    with h5py.File(merged, "r") as out, h5py.File(paths[0]) as a, h5py.File(paths[1]) as b:
        view = UnitsView([a, b])["configurations/config_01"]
        want = out["configurations/config_01"]
        assert isinstance(view, UnitsView)
        assert dict(view.attrs) == dict(want.attrs) and list(view.attrs) == list(want.attrs)
        assert list(view) == list(want) == ["energy_loss_j", "trials"]
        assert list(view["trials"]) == ["1", "2"]
        assert view["energy_loss_j"][()].tolist() == want["energy_loss_j"][()].tolist() == [1.0]
        assert "trials/2/processed" in view and "trials/3" not in view
        assert "unit_step_id" not in UnitsView([a, b]).attrs
