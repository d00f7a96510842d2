"""Step ids are made in one place and keep their documented shape (unit file names depend on them)."""

from __future__ import annotations

from protocol_runner.protocol.step_ids import calibration_id, step_id, trial_id


def test_ids_have_the_documented_shape() -> None:
    assert trial_id(3, "on", 2) == "trial:k03:on:2"
    assert calibration_id("A", "before") == "cal:A:before"
    assert step_id("check", set_name="A", key=12) == "check:A:k12"
    assert step_id("check", "brace-off", set_name="A") == "check:A:brace-off"
    assert step_id("process", key=7) == "process:k07"
    assert step_id("compare", "stiffness") == "compare:stiffness"
    assert step_id("report") == "report"


def test_no_module_but_step_ids_spells_an_id() -> None:
    import re
    from pathlib import Path

    import protocol_runner

    root = Path(protocol_runner.__file__).parent
    spelled = re.compile(r'f"(cal|trial|check|process|fit|compare):')
    found = [
        str(p.relative_to(root))
        for p in root.rglob("*.py")
        if p.name != "step_ids.py" and spelled.search(p.read_text(encoding="utf-8"))
    ]
    assert found == []


def test_a_brace_off_trial_belongs_to_its_brace_on_trial() -> None:
    """The simulator draws a trial's friction spread once for the pair (the twin subtracts that robot)."""
    from protocol_runner.protocol.step_ids import trial_of

    assert trial_of(trial_id(3, "off", 2)) == trial_id(3, "on", 2) == trial_of(trial_id(3, "on", 2))
    assert trial_of(calibration_id("A", "before")) == "cal:A:before"
