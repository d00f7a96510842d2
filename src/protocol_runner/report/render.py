"""Render a `ReportData` as one self-contained HTML file (jinja2, autoescaped, figures inline); the
template environment, the output path's checks and the atomic write are shared with the comparison page
(`compare.py`).

The file references nothing outside itself: figures are PNG data URIs, the CSS is inline, links are
in-page anchors only; it prints (`@media print`) and reads offline. Regenerating it from the same archive
gives the same bytes except the generation time, which is one element (`id="generated-utc"`).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

import jinja2
from markupsafe import Markup, escape

from protocol_runner import __version__
from protocol_runner.analysis.reference import load_reference_dataset
from protocol_runner.archive.outputs import create_new, refuse_special, temporary_beside
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.wording import counted
from protocol_runner.report.declared import declared_citations, declared_text
from protocol_runner.report.differences import declared_differences, declared_repeatability
from protocol_runner.report.evaluate import TUNED_LABEL, evaluate_expectations, format_p
from protocol_runner.report.figure_plan import (
    FigureSet,
    comparison_axis,
    configurations_of,
    distinct_comparisons,
    model_comparisons,
    slug,
)
from protocol_runner.report.headline import campaign_stats, headline_stats
from protocol_runner.report.load import load_report_data
from protocol_runner.report.model import BoucWenFit, Configuration, ReportData, factor_names
from protocol_runner.report.settings_view import format_quantity
from protocol_runner.resources import templates_dir

if TYPE_CHECKING:
    from protocol_runner.report.predictions import Prediction

TEMPLATE = "report.html.j2"

#: Section ids of the report, in document order (the table of contents links to these).
SECTIONS: tuple[tuple[str, str], ...] = (
    ("summary", "Summary"),
    ("expectations", "Expectations"),
    ("configurations", "Configurations"),
    ("comparisons", "Comparisons"),
    ("energy-loss", "Energy loss"),
    ("reference", "Reference data"),
    ("models", "Models"),
    ("test-matrix", "Test matrix"),
    ("calibration", "Calibration checks"),
    ("session", "Session details"),
    ("protocol", "Protocol as run"),
)


def generate_report(
    archive_path: Path,
    output: Path | None = None,
    *,
    reference: Path | None = None,
    workers: int | None = None,
) -> Path:
    """Read `archive_path` (archive.h5 or its session directory), write the HTML report (by default
    `report.html` beside the archive) and return its path. `reference`: an EMU dataset (CSV or .mat,
    docs/report.md) added to the archive's; `workers`: processes reading the archive and drawing figures
    (None: 2 for a large archive on 2+ cores, else 1). `InvalidInput` for an unreadable archive or reference.
    """
    data = load_report_data(archive_path, workers=workers)
    if reference is not None:
        ref = load_reference_dataset(Path(reference))
        data = dataclasses.replace(data, references=(*data.references, ref))
    output = Path(output or Path(data.session.archive_path).parent / "report.html")
    return render_with_predictions(data, output, workers=workers)


def render_with_predictions(
    data: ReportData,
    output: Path,
    *,
    workers: int | None = None,
    record: Callable[[tuple[Prediction, ...]], object] | None = None,
) -> Path:
    """`render_report`, with the predictions (from the archive, checked or just written by the caller) made on
    a process of their own while the figures are drawn (here if none can start); `record(predictions)` runs
    before the page is written (the session and `--reprocess` store them in the archive)."""
    from protocol_runner.report.predictions import predictions  # the compiled model: only run here

    archive = Path(data.session.archive_path)
    with ProcessPoolExecutor(1) as aside:
        made = aside.submit(predictions, archive, data.protocol_text)

        def predicted() -> tuple[Prediction, ...]:
            try:
                out = made.result()
            except BrokenProcessPool:
                out = predictions(archive, data.protocol_text)
            if record is not None:
                record(out)
            return out

        return render_report(data, output, workers=workers, predicted=predicted)


def render_report(
    data: ReportData,
    output: Path,
    *,
    generated_utc: str | None = None,
    workers: int | None = None,
    predicted: Callable[[], tuple[Prediction, ...]] | None = None,
) -> Path:
    """Write the report of `data` to `output` atomically (temporary file + rename); return `output`.
    `predicted` gives the model predictions when they are computed elsewhere (by default: here)."""
    html = render_html(data, generated_utc=generated_utc, workers=workers, predicted=predicted)
    output = checked_output(output, "Report", "report.html")
    write_atomically(output, html)
    return output


def render_html(
    data: ReportData,
    *,
    generated_utc: str | None = None,
    workers: int | None = None,
    predicted: Callable[[], tuple[Prediction, ...]] | None = None,
) -> str:
    """The report of `data` as an HTML string, its figures drawn with `workers` (`figures.assemble_figures`;
    `predicted`: as `render_report`)."""
    if generated_utc is None:
        generated_utc = datetime.now(UTC).replace(microsecond=0).isoformat().replace("+00:00", "Z")
    if predicted is None:
        from protocol_runner.report.predictions import predictions  # the compiled model: only run here

        predicted = functools.partial(predictions, Path(data.session.archive_path), data.protocol_text)
    from protocol_runner.report.figures import assemble_figures  # matplotlib: only where figures are drawn

    context = _context(data, assemble_figures(data, workers), generated_utc, predicted())
    return str(_environment().get_template(TEMPLATE).render(**context))


def template_environment(*, keep_trailing_newline: bool = False) -> jinja2.Environment:
    """The package's templates: HTML-escaped, every variable required, block tags without stray lines."""
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(templates_dir())),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=keep_trailing_newline,
    )


def checked_output(output: Path, page: str, example: str) -> Path:
    """`output` as a Path, or InvalidInput when it is a directory, exists and is not a regular file (a
    symbolic link, a device, a FIFO: archive/outputs.py), or its folder does not exist (`page` names the
    page in the message, `example` is a file name to suggest)."""
    output = Path(output)
    if output.is_dir() and not output.is_symlink():
        raise InvalidInput(f"{page} output {output} is a directory; give a file name such as {example}.")
    refuse_special(output, f"{page} output")
    if not output.parent.is_dir():
        raise InvalidInput(f"{page} output directory {output.parent} does not exist.")
    return output


def write_atomically(output: Path, text: str) -> None:
    """Write `text` to `output` through a temporary file and a rename: a reader never sees half a page.

    A path that is not valid UTF-8 (a session directory named with a byte of another encoding) shows in the
    page with U+FFFD where that byte was: the page itself is always valid UTF-8."""
    refuse_special(output, "output")  # checked again just before the write: never replaced by a rename
    page = text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
    tmp = temporary_beside(output)
    try:
        with create_new(tmp) as fh:
            fh.write(page)
        os.replace(tmp, output)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@functools.cache
def _environment() -> jinja2.Environment:
    """The report's template environment, one per process: it keeps the compiled template."""
    env = template_environment(keep_trailing_newline=True)
    env.filters.update(num=_num, pm=_pm, slug=slug, ci=_ci, counted=counted, p=format_p)
    return env


def _num(value: object, digits: int = 2) -> str:
    if value is None:
        return "—"
    try:
        number = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return str(value)
    if not math.isfinite(number):
        return "—"
    return f"{number:.{digits}f}"


def _pm(mean: float, std: float, digits: int = 2) -> str:
    if not (math.isfinite(mean) and math.isfinite(std)):
        return _num(mean, digits)  # "—" for a mean that is not finite
    return f"{mean:.{digits}f} ± {std:.{digits}f}"


def _ci(low: float, high: float, digits: int = 2) -> str:
    if not (math.isfinite(low) and math.isfinite(high)):
        return "—"
    return f"[{low:.{digits}f}, {high:.{digits}f}]"


def varying_levels(data: ReportData) -> dict[int, str]:
    """Per configuration key, what sets it apart in its set: the level of each factor (and the trajectory)
    that differs between the set's configurations, e.g. "bungee stiff, brake light"; "" for a set of one
    configuration, or of configurations that differ in nothing declared."""
    by_set: dict[str, list[Configuration]] = {}
    for cfg in data.configurations:
        by_set.setdefault(cfg.set_name, []).append(cfg)
    out: dict[int, str] = {}
    for configs in by_set.values():
        names = factor_names(configs)
        varying = [n for n in names if len({c.level(n) for c in configs}) > 1]
        moves = len({c.settings.trajectory or c.profile for c in configs}) > 1
        for c in configs:
            parts = [f"{n} {c.level(n)}" for n in varying if c.level(n) is not None]
            if moves:
                parts.append(f"trajectory {c.settings.trajectory or c.profile}")
            out[c.key] = ", ".join(parts)
    return out


def _context(
    data: ReportData, figures: FigureSet, generated_utc: str, predicted: tuple[Prediction, ...]
) -> dict[str, object]:
    # every configuration in key order: its joints' parts and the headline statistics of each joint (and
    # of all joints together, last, with several)
    views = [(data.joint_configurations(key), headline_stats(data, key)) for key in data.keys]
    campaign = [s for key in data.keys if (s := campaign_stats(data, key)) is not None]
    return {
        "data": data,
        "session": data.session,
        "sections": SECTIONS,
        "figures": figures,
        "comparisons": distinct_comparisons(data),
        "model_comparisons": model_comparisons(data),
        "fitted": [c for c in data.configurations if c.bouc_wen is not None],
        "multi": data.multi_joint,
        "views": views,
        "campaign": campaign,
        "predictions": predicted,
        "element_fitted": [c for c in data.configurations if c.element_fit is not None],
        "factor_names": factor_names(data.configurations),
        "quantity": format_quantity,
        "axis_of": lambda comp: comparison_axis(comp, configurations_of(data, comp.configurations)),
        "expectations": evaluate_expectations(data),
        "cite": declared_citations(data.protocol_text),
        "tuned_label": TUNED_LABEL,
        "headline": [s for _, stats in views for s in stats],
        "varying": varying_levels(data),
        "protocol_title": declared_text(data.protocol_text, "title"),
        "protocol_description": declared_text(data.protocol_text, "description"),
        "repeatability": declared_repeatability(data),
        "differences_of": lambda comp: declared_differences(data, comp),
        "limits_text": limits_text,
        "generated_utc": generated_utc,
        "software_version": __version__,
        "configs_of": lambda comp, joint=None: configurations_of(data, comp.configurations, joint),
        "total_of": data.total,
        "parameter_cell": _parameter_cell,
    }


def _parameter_cell(fit: BoucWenFit, index: int, digits: int = 4) -> Markup:
    """A Bouc-Wen parameter (0: A, 1: n, 2-7: β1-β6) with its 95 % interval on the next two lines (the
    table stays narrow), or "unidentified" there when the data do not identify it (an interval covering
    most of its plausible range says nothing about the joint); the value alone when neither is recorded."""
    values = (fit.A, fit.n, *fit.beta)
    if index >= len(values) or not math.isfinite(values[index]):
        return Markup("—")
    value = escape(_num(values[index], digits))
    if index < len(fit.parameter_identified) and not fit.parameter_identified[index]:
        return value + Markup('<br><span class="se">unidentified</span>')
    if index < min(len(fit.param_interval_low), len(fit.param_interval_high)):
        low, high = fit.param_interval_low[index], fit.param_interval_high[index]
        if math.isfinite(low) and math.isfinite(high):
            return Markup('{}<br><span class="se">[{},<br>{}]</span>').format(
                value, _num(low, digits), _num(high, digits)
            )
    return value


_PHRASES: dict[str, str] = {
    "max_settle_error_deg": "settle error ≤ {v} deg",
    "settle_error_deg": "settle error ≤ {v} deg",
    "max_drift_deg": "drift within the set ≤ {v} deg",
    "max_time_constant_change_s": "time-constant change within the set ≤ {v} s",
}


def _number(value: object) -> str:
    return f"{value:g}" if isinstance(value, int | float) and not isinstance(value, bool) else str(value)


def limits_text(raw: str) -> str:
    """E.g. `{"max_settle_error_deg": 3.0, "time_constant_s": [0.1, 0.35]}` ->
    "settle error ≤ 3 deg; time constant 0.1-0.35 s". Text that is not a JSON object is returned as is."""
    try:
        limits = json.loads(raw) if raw else {}
    except ValueError:
        return raw
    if not isinstance(limits, dict):
        return raw
    parts: list[str] = []
    for name, value in limits.items():
        if name == "time_constant_s" and isinstance(value, list) and len(value) == 2:
            parts.append(f"time constant {_number(value[0])}-{_number(value[1])} s")
        elif name in _PHRASES:
            parts.append(_PHRASES[name].format(v=_number(value)))
        else:
            parts.append(f"{name.replace('_', ' ')} {_number(value)}")
    return "; ".join(parts) if parts else "none recorded"
