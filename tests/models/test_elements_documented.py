"""The element registry (models/elements.py) is what docs/protocol.md promises a test engineer: every
parameter's unit, default, whether the fit estimates it and its allowed interval, as documented; the
lever spring's fit starts as docs/analysis.md lists them."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from protocol_runner.errors import InvalidInput
from protocol_runner.models.element_types import ELEMENT_TYPES, ElementType
from protocol_runner.models.elements import build_element

DOCS = Path(__file__).resolve().parents[2] / "docs"
PROTOCOL_DOC = (DOCS / "protocol.md").read_text(encoding="utf-8")
ANALYSIS_DOC = (DOCS / "analysis.md").read_text(encoding="utf-8")
ROW = re.compile(r"^\| `(\w+)` \| `([\w-]+)` \| (.*?) \| (yes)? *\| (.*) \|$")


def _documented(name: str) -> tuple[str, dict[str, tuple[str, str, bool, str]]]:
    """(kind, {parameter: (unit, default, fit, meaning)}) of a type's section of docs/protocol.md."""
    head = re.search(rf"^### `{name}` \((\w+)\)$", PROTOCOL_DOC, re.MULTILINE)
    assert head is not None, name
    section = PROTOCOL_DOC[head.end() :].split("\n### ", 1)[0].split("\n## ", 1)[0]
    rows = {}
    for line in section.splitlines():
        m = ROW.match(line)
        if m:
            rows[m[1]] = (m[2], m[3], m[4] == "yes", m[5])
    return head[1], rows


def _number(text: str) -> float:
    return math.inf if text == "inf" else -math.inf if text == "-inf" else float(text)


@pytest.mark.parametrize("etype", list(ELEMENT_TYPES.values()), ids=lambda t: t.name)
def test_every_parameter_is_as_documented(etype: ElementType) -> None:
    kind, rows = _documented(etype.name)
    assert kind == etype.kind
    assert list(rows) == list(etype.parameters)
    for param, spec in etype.parameters.items():
        unit, default, fit, meaning = rows[param]
        assert unit == (spec.unit or "-"), param
        assert fit == spec.fittable, param
        if spec.default is None:
            assert default == "required", param
        elif isinstance(spec.default, str):
            assert default == f"`{spec.default}`", param
        else:
            assert _number(default) == spec.default, param
        allowed = re.search(r"\(allowed (\S+) to (\S+)\)$", meaning)
        if spec.bounds is None:
            assert allowed is None, param
        else:
            assert allowed is not None, param
            assert (_number(allowed[1]), _number(allowed[2])) == pytest.approx(spec.bounds, rel=1e-12), param
        assert meaning.startswith(spec.doc), param


@pytest.mark.parametrize("etype", list(ELEMENT_TYPES.values()), ids=lambda t: t.name)
def test_the_documented_interval_is_enforced_at_both_ends(etype: ElementType) -> None:
    """A value at either end of a parameter's finite interval is accepted, one just beyond it refused,
    naming the element and the parameter."""
    base = _valid_params(etype)
    for param, spec in etype.parameters.items():
        if spec.bounds is None or spec.shape not in ("number", "integer"):
            continue
        for end, outside in ((spec.bounds[0], -1.0), (spec.bounds[1], 1.0)):
            if not math.isfinite(end):
                continue
            built = build_element("e", etype.name, {**base, param: end})
            assert built.params[param] == end
            beyond = end + outside * max(1.0, abs(end) * 1e-6)
            lo, hi = spec.bounds
            message = f"element 'e' \\({etype.name}\\): parameter '{param}' must lie in \\[{lo:g}, {hi:g}\\]"
            with pytest.raises(InvalidInput, match=message):
                build_element("e", etype.name, {**base, param: beyond})


def _valid_params(etype: ElementType) -> dict[str, object]:
    """Every required parameter at a value inside its interval."""
    out: dict[str, object] = {}
    for param, spec in etype.parameters.items():
        if spec.default is not None:
            continue
        if spec.shape == "pair":
            out[param] = [0.0, 1.0]
        elif spec.bounds is None:
            out[param] = 0.0
        else:
            lo, hi = spec.bounds
            out[param] = min(max(1.0, lo), hi)
    return out


def test_the_lever_springs_fit_starts_are_the_documented_ones() -> None:
    """docs/analysis.md: the lever spring's fit starts from 10 and 60 mm of Max_Preload and -15 and +15 deg
    of zero offset (besides the declared values), within 0-100 mm and +-40 deg."""
    row = next(line for line in ANALYSIS_DOC.splitlines() if line.startswith("| `lever_spring`"))
    assert "0-100 mm, ±40°" in row and "10, 60 mm; −15°, +15°" in row
    spring = ELEMENT_TYPES["lever_spring"].parameters
    assert spring["max_preload_mm"].fit_starts == (10.0, 60.0)
    assert spring["max_preload_mm"].bounds == (0.0, 100.0)
    assert spring["zero_offset_deg"].fit_starts == (-15.0, 15.0)
    assert spring["zero_offset_deg"].bounds == (-40.0, 40.0)


def test_every_fittable_parameter_gives_the_fit_a_usable_scale_and_starts() -> None:
    """The element fit hands fit_scale to scipy's least_squares as x_scale (must be positive and finite)
    and starts from fit_starts, which must lie in the parameter's interval."""
    for etype in ELEMENT_TYPES.values():
        for param, spec in etype.parameters.items():
            if not spec.fittable:
                continue
            assert spec.bounds is not None and spec.bounds[0] < spec.bounds[1], param
            assert 0.0 < spec.fit_scale < math.inf, (etype.name, param)
            for start in spec.fit_starts:
                assert spec.bounds[0] <= start <= spec.bounds[1], (etype.name, param)
