"""The report's Bouc-Wen table: each parameter with its 95 % interval, "unidentified" where the data do not
identify it, never a "±" standard error; the functionals the loops determine in their own table."""

from __future__ import annotations

import dataclasses
from pathlib import Path

from protocol_runner.report.load import load_report_data
from protocol_runner.report.render import _parameter_cell, render_html


def _table(page: str, marker: str) -> str:
    start = page.index(marker)
    return page[start : page.index("</table>", start)]


def test_parameters_print_their_interval_or_unidentified_and_never_a_standard_error(
    small_archive: Path,
) -> None:
    data = load_report_data(small_archive, verify=False)
    fitted = [c for c in data.configurations if c.bouc_wen is not None]
    assert fitted
    cfg = fitted[0]
    assert cfg.bouc_wen is not None
    bw = dataclasses.replace(
        cfg.bouc_wen,
        param_interval_low=(1.0, 0.5, *(-1.0,) * 6),
        param_interval_high=(2.0, 3.0, *(1.0,) * 6),
        parameter_identified=(True, False, *(True,) * 6),
        functionals=(("loop energy per cycle", "J", 12.5, 12.0, 13.0),),
    )
    assert "[1.0000,<br>2.0000]" in str(_parameter_cell(bw, 0))
    assert "unidentified" in str(_parameter_cell(bw, 1)) and "[" not in str(_parameter_cell(bw, 1))
    configurations = tuple(
        dataclasses.replace(c, bouc_wen=bw) if c is cfg else c for c in data.configurations
    )
    page = render_html(
        dataclasses.replace(data, configurations=configurations),
        generated_utc="T",
        workers=1,
        predicted=lambda: (),
    )
    table = _table(page, '<table class="bouc-wen">')
    assert "±" not in table and "unidentified" in table
    functionals = _table(page, '<table id="models-bouc-wen-functionals">')
    assert "loop energy per cycle (J) [95 %]" in functionals
    assert "12.500 [12.000, 13.000]" in functionals
