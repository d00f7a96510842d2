"""`--export` and `--compare`: results a lab can publish (tidy CSV tables; two sessions side by side)."""

from __future__ import annotations

from pathlib import Path

from .commands import _archive_of, _say
from .errors import EXIT_OK


def export(path: Path, output: Path | None) -> int:
    """`--export`: cycles.csv, trials.csv and configurations.csv (default: `tables/` beside the archive)."""
    from .report.tidy import export_tables

    archive = _archive_of(path)
    out_dir = output if output is not None else archive.parent / "tables"
    files = export_tables(archive, out_dir)
    _say(f"wrote {', '.join(f.name for f in files)} to {out_dir}")
    return EXIT_OK


def compare(a: Path, b: Path, output: Path | None) -> int:
    """`--compare`: match configurations by settings, print the table and write the HTML page."""
    from .report.compare import compare_archives, render_comparison

    archive_a, archive_b = _archive_of(a), _archive_of(b)
    result = compare_archives(archive_a, archive_b)
    print(result.table())
    out = output if output is not None else Path("comparison.html")
    render_comparison(result, out)
    _say(f"comparison: {out}")
    return EXIT_OK
