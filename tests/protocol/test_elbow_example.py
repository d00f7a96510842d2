"""protocols/elbow_example.yaml, the campaign written from docs/protocol.md alone: it
validates, plans and dry-runs, the doc shows it in full, and each mistake a test engineer makes in it gets
the one located line the doc's "Errors" table promises (exit 2, no traceback)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import h5py
import pytest

from protocol_runner.cli import main
from protocol_runner.protocol.loader import load_protocol

REPO = Path(__file__).resolve().parents[2]
ELBOW = REPO / "protocols" / "elbow_example.yaml"
ELBOW_TEXT = ELBOW.read_text(encoding="utf-8")
DOC = (REPO / "docs" / "protocol.md").read_text(encoding="utf-8")


def test_the_doc_shows_the_example_exactly_as_shipped() -> None:
    assert f"```yaml\n{ELBOW_TEXT}```" in DOC


def test_elbow_example_validates_and_expands_to_the_documented_matrix() -> None:
    loaded = load_protocol(ELBOW)
    p = loaded.protocol
    assert p.rig.joint.name == "elbow_flexion" and p.rig.joint.range_deg == (0.0, 130.0)
    rows = [
        (c.key, c.levels["damping"], c.levels["torsion"], c.levels["speed"], c.trajectory)
        for _, c in p.configurations()
    ]
    # full factorial damping x torsion (torsion fastest) at slow, keys from 1; then OFAT around d1 k1
    assert rows == [
        (1, "d0", "k0", "slow", "sine"),
        (2, "d0", "k1", "slow", "sine"),
        (3, "d0", "k2", "slow", "sine"),
        (4, "d1", "k0", "slow", "sine"),
        (5, "d1", "k1", "slow", "sine"),
        (6, "d1", "k2", "slow", "sine"),
        (7, "d1", "k1", "slow", "tri"),
        (8, "d1", "k1", "fast", "sine"),
    ]


def test_elbow_plan_json_binds_the_device_and_pairs_every_trial_with_a_brace_off_twin(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["--plan", str(ELBOW), "--json"]) == 0
    steps = json.loads(capsys.readouterr().out)["steps"]
    trials = [s for s in steps if s["kind"] == "trial"]
    on = [s for s in trials if s["brace"] == "on"]
    off = [s for s in trials if s["brace"] == "off"]
    assert len(on) == len(off) == 8 * 3
    assert {s["derived_from"] for s in off} == {s["id"] for s in on}
    k6 = next(s for s in on if s["configuration"] == 6)
    assert k6["settings"]["torsion"] == {"level": "k2", "stiffness_nm_per_deg": 0.2}
    device = {e["name"]: e for e in k6["device"]}
    assert device["torsion"]["stiffness_nm_per_deg"] == 0.2 and device["torsion"]["neutral_deg"] == 60.0
    assert device["damper"]["damping_nm_s_per_deg"] == 0.02
    assert device["brake"]["torque_nm"] == 0.5
    assert all("device" not in s for s in off)
    tri = next(s for s in on if s["configuration"] == 7)["trajectory"]
    assert tri["profile"] == "triangle" and tri["range_deg"] == [20.0, 110.0] and tri["speed_deg_s"] == 20.0
    cal = [s for s in steps if s["kind"] == "calibration_check"]
    assert len(cal) == 4 and all(
        0 <= s["trajectory"]["from_deg"] + s["trajectory"]["step_deg"] <= 130 for s in cal
    )


def test_elbow_dry_run_loses_the_brake_and_damper_energy_per_cycle(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Configurations 1 (brake only) and 4 (brake and damper), 20 deg/s peak over 20-110 deg: the brake, a
    Dahl friction of level T relaxing over x0, loses 4*T*(A - x0*(1 - exp(-2A/x0))) per cycle (4*T*A less
    the rounded reversals), the damper pi*c*omega*A^2 more (the elements' facts)."""
    session = tmp_path / "s"
    assert main([str(ELBOW), "--dry-run", "--only", "1,4", "--session", str(session)]) == 0
    capsys.readouterr()
    amplitude_rad = math.radians(45.0)
    omega = 20.0 / 45.0  # peak speed / amplitude (Eq 25)
    transition_rad = math.radians(2.0)
    brake_j = 4 * 0.5 * (amplitude_rad - transition_rad * (1 - math.exp(-2 * amplitude_rad / transition_rad)))
    damper_j = math.pi * math.degrees(0.02) * omega * amplitude_rad**2
    with h5py.File(session / "archive.h5", "r") as h5:
        e1 = float(h5["configurations/config_01/joints/elbow_flexion/energy_loss_j"].attrs["mean_j"])
        e4 = float(h5["configurations/config_04/joints/elbow_flexion/energy_loss_j"].attrs["mean_j"])
    assert e1 == pytest.approx(brake_j, rel=0.05)
    # the simulator's between-trial spread (device dissipation CV 3 %, robot friction 5 %) puts about 6 % of
    # sampling error on a difference of two 3-trial means
    assert e4 - e1 == pytest.approx(damper_j, rel=0.12)
    # no expectation of this campaign is simulator-tuned: the dry-run note must not claim thesis findings
    html = (session / "report.html").read_text(encoding="utf-8")
    note = html[html.index('id="dry-run-note"') :].split("</p>", 1)[0]
    assert "thesis findings" not in note and "not from a measurement" in note
    assert "brace off (simulated clock)" in " ".join(html.split())


# ------------------------------------------------------------------------------ a test engineer's mistakes

MISTAKES = [
    # (mistake, edit old -> new, the line to expect it on (text after the edit), message as in the doc)
    (
        "typo in an element parameter",
        ("damping_nm_s_per_deg: damping.", "damping_nm_s_per_degree: damping."),
        "damping_nm_s_per_degree:",
        "device.elements[1].damping_nm_s_per_degree: unknown parameter of viscous_damper; did you mean "
        "'damping_nm_s_per_deg'? (parameters: damping_nm_s_per_deg)",
    ),
    (
        "typo in an element type",
        ("type: torsion_spring", "type: torsion-spring"),
        "type: torsion-spring",
        "device.elements[0].type: unknown element type 'torsion-spring'; did you mean 'torsion_spring'?",
    ),
    (
        "a level's value outside the element's bounds",
        ("d1: {damping_nm_s_per_deg: 0.02,", "d1: {damping_nm_s_per_deg: -0.02,"),
        "d1: {damping_nm_s_per_deg: -0.02,",
        "factors.damping.d1.damping_nm_s_per_deg: element 'damper' (viscous_damper): parameter "
        "'damping_nm_s_per_deg' must lie in [0, inf], got -0.02 (level 'd1' of damping, bound by "
        "device.elements[1].damping_nm_s_per_deg) (configurations 4-8 in sets 'factorial', 'speed')",
    ),
    (
        "a unit written into a constant",
        ("neutral_deg: 60}", "neutral_deg: 60 deg}"),
        "neutral_deg: 60 deg}",
        "device.elements[0].neutral_deg: element 'torsion' (torsion_spring): parameter 'neutral_deg' must "
        "be a number, got '60 deg' (every configuration)",
    ),
    (
        "a bound factor the generator does not set",
        ("fixed: {speed: slow}", "fixed: {}"),
        "  sine: {kind: sinusoid",
        "trajectories.sine.speed_deg_s: bound to speed.speed_deg_s but the configuration sets no level of "
        "'speed'; give speed a level in the row, or in the generator's `fixed` or `baseline` "
        "(configurations 1-6 in set 'factorial')",
    ),
    (
        "a unit that is not in the table",
        ("fast: {speed_deg_s: 40}", "fast: {speed_deg_s: 40}\n    crawl: {speed_rad_s: 0.3}"),
        "crawl:",
        "factors.speed.crawl: 'speed_rad_s': the unit _rad_s is not one of the unit suffixes (it would read "
        "as _s, s); use one of: ",
    ),
    (
        "an unknown factor in a generator's fixed levels",
        ("fixed: {speed: slow}", "fixed: {speed: slow, velocity: fast}"),
        "fixed: {speed: slow, velocity",
        "sets[0].full_factorial.fixed.velocity: unknown factor 'velocity' (declared: damping, torsion, speed)",
    ),
    (
        "a generator over an unknown level",
        ("vary: {speed: [fast]}", "vary: {speed: [fast, medium]}"),
        "vary: {speed: [fast, medium]}",
        "sets[1].one_factor_at_a_time.vary.speed[1]: unknown level 'medium' of speed (known: slow, fast)",
    ),
    (
        "`all` misspelt",
        ("factors: {damping: all,", "factors: {damping: al,"),
        "factors: {damping: al,",
        "sets[0].full_factorial.factors.damping: input should be a valid list or 'all' (got 'al')",
    ),
    (
        "a generator naming an unknown trajectory",
        ("levels: {slow: tri,", "levels: {slow: triangle,"),
        "levels: {slow: triangle,",
        "sets[1].one_factor_at_a_time.trajectory_by_level.levels.slow: unknown trajectory 'triangle' "
        "(known: sine, tri)",
    ),
    (
        "a trajectory over the elbow's range",
        ("sine: {kind: sinusoid, range_deg: [20, 110]", "sine: {kind: sinusoid, range_deg: [-10, 110]"),
        "  sine: {kind: sinusoid",
        "trajectories.sine.range_deg: trajectory 'sine' (sinusoid): range_deg: [-10, 110] deg is outside the "
        "joint's range [0, 130] deg (configurations 1-6, 8 in sets 'factorial', 'speed')",
    ),
    (
        "a park angle against a stop",
        (
            "    - {name: brake,",
            "    - {name: stops, type: rom_stops, range_deg: [60, 120], stop_stiffness_nm_per_deg: 20}\n"
            "    - {name: brake,",
        ),
        "    full_factorial:",
        "sets[0].full_factorial: the park angle 45 deg is outside the stops [60, 120] deg of element "
        "'stops': between trials the joint would rest against a stop (choose "
        "rig_overrides...safety.park_angle_deg inside every stop range) (configurations 1-6 in set 'factorial')",
    ),
    (
        "an expectation naming a key the matrix lacks",
        ("configurations: [4, 5, 6]\n    than:", "configurations: [4, 5, 12]\n    than:"),
        "configurations: [4, 5, 12]",
        "expectations[0].configurations[2]: no configuration has key 12 (keys: 1-8)",
    ),
    (
        "binding to a quantity no level has (a typo)",
        (
            "stiffness_nm_per_deg: torsion.stiffness_nm_per_deg",
            "stiffness_nm_per_deg: torsion.stiffnes_nm_per_deg",
        ),
        "stiffness_nm_per_deg: torsion.stiffnes_nm_per_deg",
        "device.elements[0].stiffness_nm_per_deg: bound to torsion.stiffnes_nm_per_deg: no level of torsion has a "
        "quantity 'stiffnes_nm_per_deg' (its levels have stiffness_nm_per_deg)",
    ),
    (
        "a yes where a number belongs",
        ("speed.speed_deg_s, periods: 6}", "speed.speed_deg_s, periods: yes}"),
        "  sine: {kind: sinusoid",
        "trajectories.sine.periods: expected a number, got True (YAML reads yes, no, on, off, true and false "
        "as booleans)",
    ),
    (
        "a negative time in the calibration step",
        ("hold_s: 4.0, settle_s: 1.0}", "hold_s: -4.0, settle_s: 1.0}"),
        "calibration_step: {",
        "calibration_step.hold_s: input should be greater than 0 (got -4.0)",
    ),
    (
        "a tab in the indentation",
        ("  damping:\n    d0", "  damping:\n\td0"),
        "\td0",
        "YAML syntax error: while scanning for the next token, found character '\\t' that cannot start any "
        "token (indent with spaces: YAML does not allow tabs)",
    ),
]


@pytest.mark.parametrize(
    ("edit", "needle", "expected"), [m[1:] for m in MISTAKES], ids=[m[0] for m in MISTAKES]
)
def test_a_mistake_in_the_elbow_campaign_gets_one_located_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], edit: tuple[str, str], needle: str, expected: str
) -> None:
    old, new = edit
    assert ELBOW_TEXT.count(old) == 1, old
    text = ELBOW_TEXT.replace(old, new)
    path = tmp_path / "elbow.yaml"
    path.write_text(text, encoding="utf-8")
    assert main(["--validate", str(path)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln.removeprefix("run-protocol: ") for ln in err.strip().splitlines()]
    # one line per mistake, not one per configuration (a stop that holds no park angle: one per set)
    assert len(lines) == (2 if "park angle" in expected else 1), err
    line = text[: text.index(needle)].count("\n") + 1
    assert lines[0].startswith(f"{path}:{line}: "), err
    assert expected in lines[0], err
    assert expected.split(" (")[0] in DOC, f"docs/protocol.md does not show: {expected}"
