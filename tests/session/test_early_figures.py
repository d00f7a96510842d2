"""A dry run draws each configuration's figures in the analysis worker; the report only assembles them."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

from protocol_runner.report.figure_cache import cache_dir_of, lookup
from protocol_runner.report.figures import draw_configuration
from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import generate_report


def _without_time(html: str) -> str:
    return re.sub(r'id="generated-utc"[^<]*', "", html)


def test_the_session_stores_figures_the_report_then_uses(reference_archive: Path) -> None:
    data = load_report_data(reference_archive)
    cache = cache_dir_of(reference_archive)
    assert cache == reference_archive.parent / "figures"
    for cfg in data.configurations:
        stored = lookup(cache, cfg)  # drawn from the units, matching what the report reads from the archive
        assert stored is not None, cfg.name
        assert stored == draw_configuration(cfg)


def test_the_report_is_the_same_without_the_stored_figures(reference_archive: Path, tmp_path: Path) -> None:
    """--report on an archive without the figure folder draws everything itself, to the same HTML."""
    alone = tmp_path / "archive.h5"
    shutil.copy(reference_archive, alone)
    assert not cache_dir_of(alone).exists()
    regenerated = generate_report(alone, tmp_path / "report.html").read_text(encoding="utf-8")
    session_report = (reference_archive.parent / "report.html").read_text(encoding="utf-8")
    regenerated = regenerated.replace(str(alone), str(reference_archive))  # the report names its archive
    assert _without_time(regenerated) == _without_time(session_report)
