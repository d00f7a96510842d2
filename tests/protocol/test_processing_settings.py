"""The protocol's `processing` section reaches the analysis unchanged: every value a test engineer writes
there is the value the processing uses (docs/protocol.md "processing"), the rest keep the thesis defaults."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.processing import SECTION_PATHS, processing_settings

ANKLE = Path(__file__).resolve().parents[2] / "protocols" / "ankle_phase2.yaml"
SHIPPED = (
    "  transition: {tolerance_deg: 5.0, points: 3}\n"
    "  filter: {kind: butterworth, order: 10, cutoff: 0.10}\n"
    "  brace_off_scaling: {tolerance_deg: 0.1, max_iterations: 6}\n"
    "  subtraction: equal_angle\n"
    "  centre_for_fit: true\n"
)


def with_processing(tmp_path: Path, section: str) -> Path:
    text = ANKLE.read_text(encoding="utf-8")
    assert SHIPPED in text
    path = tmp_path / ANKLE.name
    path.write_text(text.replace(SHIPPED, section), encoding="utf-8")
    return path


def test_every_value_of_the_processing_section_is_the_one_the_analysis_uses(tmp_path: Path) -> None:
    path = with_processing(
        tmp_path,
        "  transition: {tolerance_deg: 2.5, points: 7}\n"
        "  filter: {kind: chebyshev, order: 4, cutoff: 0.03, ripple_db: 1.5}\n"
        "  brace_off_scaling: {tolerance_deg: 1.0, max_iterations: 4}\n"
        "  subtraction: equal_time\n"
        "  centre_for_fit: false\n",
    )
    s = processing_settings(load_protocol(path))
    assert (s.transition_tolerance_deg, s.transition_points) == (2.5, 7)
    assert (s.filter_kind, s.filter_order, s.filter_cutoff, s.chebyshev_ripple_db) == (
        "chebyshev",
        4,
        0.03,
        1.5,
    )
    assert (s.subtraction, s.centring) == ("equal_time", "none")
    # what the section does not hold keeps the thesis defaults
    defaults = ProcessingSettings()
    set_here = set(SECTION_PATHS) | {"centring"}
    for f in dataclasses.fields(ProcessingSettings):
        if f.name not in set_here:
            assert getattr(s, f.name) == getattr(defaults, f.name), f.name


def test_the_shipped_section_gives_the_thesis_processing() -> None:
    """§3.2-§3.3: 10th-order Butterworth at 0.1 of Nyquist, transition at 5 deg over 3 points, equal-angle
    subtraction; centred for the fit."""
    s = processing_settings(load_protocol(ANKLE))
    assert s == dataclasses.replace(ProcessingSettings(), centring="trial_mean")


def test_a_value_the_analysis_refuses_is_named(tmp_path: Path) -> None:
    path = with_processing(tmp_path, SHIPPED.replace("order: 10", "order: 0"))
    with pytest.raises(InvalidInput, match="order"):
        processing_settings(load_protocol(path))
