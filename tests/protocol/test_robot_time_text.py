"""The robot time a run and `--validate` announce (protocol/plan_table.robot_time_text): hours from 90
minutes, minutes from 90 seconds, seconds below (a 30 s plan was announced as "about 0 min")."""

from __future__ import annotations

import pytest

from protocol_runner.protocol.plan_table import robot_time_text


@pytest.mark.parametrize(
    ("seconds", "text"),
    [(8901.0, "2.5 h"), (5400.0, "1.5 h"), (5399.0, "90 min"), (1200.0, "20 min"), (90.0, "2 min"),
     (89.0, "89 s"), (29.6, "30 s"), (0.0, "0 s")],
)  # fmt: skip
def test_the_unit_fits_the_length(seconds: float, text: str) -> None:
    assert robot_time_text(seconds) == text
