"""The expansion of knee_phase1.yaml against the thesis's Appendix A (Tables 5-6) and plan invariants."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import CalibrationCheckStep, ChecklistStep, Plan, TrialStep
from protocol_runner.protocol.trajectories import sinusoid_deg, sinusoid_period_s

REPO = Path(__file__).resolve().parents[2]
KNEE = REPO / "protocols" / "knee_phase1.yaml"

# Thesis Table 5, transcribed: key -> (test run, brace ROM, robot ROM, friction, stiffness, speed, preload, profile)
TABLE_5 = {
    1: (5, "R1", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    2: (6, "R2", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    3: (7, "R3", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    4: (8, "R3", "Rr3", "0", "K2", "Full", "Center", "sinusoid"),
    5: (9, "R3", "Rr3", "1", "K2", "Full", "Center", "sinusoid"),
    6: (10, "R3", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    7: (11, "R3", "Rr3", "3", "K2", "Full", "Center", "sinusoid"),
    8: (3, "R3", "Rr3", "2", "K2", "Full", "First", "sinusoid"),
    9: (4, "R3", "Rr3", "2", "K2", "Full", "Last", "sinusoid"),
    10: (1, "R3", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    11: (2, "R3", "Rr3", "2", "K2", "Half", "Center", "sinusoid"),
    12: (18, "R1", "Rr1", "2", "K2", "Full", "Center", "sinusoid"),
    13: (19, "R2", "Rr2", "2", "K2", "Full", "Center", "sinusoid"),
    14: (20, "R3", "Rr3", "2", "K2", "Full", "Center", "sinusoid"),
    15: (12, "R1", "Rr1", "2", "K0", "Full", "Center", "sinusoid"),
    16: (13, "R2", "Rr2", "2", "K0", "Full", "Center", "sinusoid"),
    17: (14, "R3", "Rr3", "2", "K0", "Full", "Center", "sinusoid"),
    18: (15, "R1", "Rr1", "2", "K1", "Full", "Center", "sinusoid"),
    19: (16, "R2", "Rr2", "2", "K1", "Full", "Center", "sinusoid"),
    20: (17, "R3", "Rr3", "2", "K1", "Full", "Center", "sinusoid"),
    21: (21, "R1", "Rr1", "2", "K3", "Full", "Center", "sinusoid"),
    22: (22, "R2", "Rr2", "2", "K3", "Full", "Center", "sinusoid"),
    23: (23, "R3", "Rr3", "2", "K3", "Full", "Center", "sinusoid"),
    24: (24, "R-E", "Rr-E", "EMU", "K-EMU", "Full", "EMU", "human"),
    25: (25, "R-E", "Rr-E", "EMU", "K-EMU", "Full", "EMU", "human"),
    26: (26, "R-E", "Rr-E", "EMU", "K-EMU", "Full", "EMU", "human"),
    27: (27, "R-E", "Rr-E", "EMU", "K-EMU", "Full", "EMU", "sinusoid"),
    28: (28, "R-E", "Rr-E", "EMU", "K-EMU", "Half", "EMU", "sinusoid"),
}
ROM_DEG = {"R1": (40, 90), "R2": (20, 110), "R3": (0, 130), "R-E": (0, 110)}
FRICTION_NM = {"0": 0.0, "1": 1.25, "2": 3.75, "3": 6.25, "EMU": 3.75}
STIFFNESS = {"K0": 0.0, "K1": 4.4, "K2": 13.0, "K3": 20.0, "K-EMU": 13.0}
SPEED = {"Full": 50.0, "Half": 25.0}
# Table 6 periods (s) per key, as printed (two decimals)
TABLE_6_PERIOD = {k: 8.17 for k in range(1, 12)} | {k: 8.17 for k in (14, 17, 20, 23)}
TABLE_6_PERIOD |= {11: 16.34, 12: 3.14, 15: 3.14, 18: 3.14, 21: 3.14, 13: 5.65, 16: 5.65, 19: 5.65, 22: 5.65}
TABLE_6_PERIOD |= {27: 6.91, 28: 13.82}
FEWER_TRIALS = set(range(15, 18)) | set(range(24, 29))


@pytest.fixture(scope="module")
def plan() -> Plan:
    return expand(load_protocol(KNEE))


def trials(plan: Plan) -> list[TrialStep]:
    return [s for s in plan.steps if isinstance(s, TrialStep)]


def test_every_row_of_table_5_is_expanded(plan: Plan) -> None:
    on = {t.configuration: t for t in trials(plan) if t.brace == "on" and t.trial == 1}
    assert sorted(on) == list(range(1, 29))
    for key, (run, brace, robot, fric, stiff, speed, preload, profile) in TABLE_5.items():
        t = on[key]
        s = t.settings
        assert t.run == run, key
        assert (s.level("brace_rom"), s.level("friction"), s.level("stiffness"), s.level("preload")) == (
            brace,
            fric,
            stiff,
            preload,
        ), key
        assert s.quantity("brace_rom", "range_deg") == ROM_DEG[brace]
        assert s.quantity("friction", "friction_nm") == FRICTION_NM[fric]
        assert s.quantity("stiffness", "stiffness_n_per_mm") == STIFFNESS[stiff]
        if profile == "human":
            # a subject's motion file is the trajectory: no robot range or speed level applies
            assert t.trajectory.profile == "file" and t.trajectory.source is not None
            assert s.level("robot_rom") is None and s.level("speed") is None
        else:
            assert t.trajectory.profile == profile
            assert (s.level("robot_rom"), s.level("speed")) == (robot, speed), key
            assert s.quantity("robot_rom", "range_deg") == ROM_DEG[robot.replace("Rr", "R")]
            assert s.quantity("speed", "speed_deg_s") == SPEED[speed]
        # the device the brace-on trial runs with carries the same numbers (bindings resolved)
        device = {e["name"]: e for e in t.settings.device_json()}
        assert device["stops"]["range_deg"] == list(ROM_DEG[brace])
        assert device["brake"]["torque_nm"] == FRICTION_NM[fric]
        assert device["springs"]["stiffness_n_per_mm"] == STIFFNESS[stiff]


def test_trial_counts_three_except_where_the_thesis_ran_fewer(plan: Plan) -> None:
    for key in TABLE_5:
        n_on = sum(1 for t in trials(plan) if t.configuration == key and t.brace == "on")
        n_off = sum(1 for t in trials(plan) if t.configuration == key and t.brace == "off")
        assert n_on == n_off
        if key in FEWER_TRIALS:
            assert 1 <= n_on < 3, key
        else:
            assert n_on == 3, key


def test_derived_periods_match_table_6(plan: Plan) -> None:
    on = {t.configuration: t for t in trials(plan) if t.brace == "on" and t.trial == 1}
    for key, period in TABLE_6_PERIOD.items():
        assert on[key].trajectory.period_s == pytest.approx(period, abs=0.005), key
    assert {round(on[k].trajectory.period_s or 0, 2) for k in TABLE_6_PERIOD} == {
        8.17,
        16.34,
        3.14,
        5.65,
        6.91,
        13.82,
    }


def test_sinusoid_peak_speed_is_the_level_speed() -> None:
    # Eq 25: max velocity = amplitude * 2*pi/p, checked numerically on the sampled Eq 24 curve
    for amplitude, speed in ((65, 50), (25, 50), (55, 25)):
        p = sinusoid_period_s(amplitude, speed)
        t = [i * 1e-3 for i in range(int(p * 1000))]
        import numpy as np

        x = sinusoid_deg(np.asarray(t), amplitude, amplitude, p)
        assert float(np.max(np.abs(np.diff(x)) / 1e-3)) == pytest.approx(speed, rel=1e-3)


def test_sinusoids_run_about_eight_periods_within_the_robot_range(plan: Plan) -> None:
    for t in trials(plan):
        tr = t.trajectory
        if tr.profile != "sinusoid":
            continue
        assert tr.duration_s == pytest.approx(8 * (tr.period_s or 0))
        lo, hi = t.settings.quantity("robot_rom", "range_deg")  # type: ignore[misc]
        assert (tr.mean_deg or 0) - (tr.amplitude_deg or 0) == pytest.approx(lo)
        assert (tr.mean_deg or 0) + (tr.amplitude_deg or 0) == pytest.approx(hi)


def test_sets_follow_test_run_order_and_are_wrapped_by_calibration_checks(plan: Plan) -> None:
    runs = [t.run for t in trials(plan) if t.brace == "on" and t.trial == 1]
    assert runs == sorted(runs) == list(range(1, 29))
    for s in {t.set for t in trials(plan)}:
        idx = [i for i, step in enumerate(plan.steps) if getattr(step, "set", None) == s]
        kinds = [plan.steps[i] for i in idx]
        cal = [k for k in kinds if isinstance(k, CalibrationCheckStep)]
        assert [c.when for c in cal] == ["before", "after"]
        set_trials = [i for i in idx if isinstance(plan.steps[i], TrialStep)]
        assert plan.steps.index(cal[0]) < min(set_trials) and max(set_trials) < plan.steps.index(cal[1])


def test_brace_removal_checklist_separates_brace_on_from_brace_off(plan: Plan) -> None:
    for s in {t.set for t in trials(plan)}:
        removal = plan.step(f"check:{s}:brace-off")
        assert isinstance(removal, ChecklistStep) and removal.brace == "off"
        pos = plan.steps.index(removal)
        for i, step in enumerate(plan.steps):
            if isinstance(step, TrialStep) and step.set == s:
                assert (step.brace == "on") == (i < pos)


def test_checklists_name_the_settings_to_make(plan: Plan) -> None:
    c = plan.step("check:friction:k07")
    assert isinstance(c, ChecklistStep)
    text = "\n".join(c.items)
    assert "1.25 turns" in text and "6.25 N*m" in text and "13 N/mm" in text
    assert "position 3" in text and "0-130 deg" in text and "8 mm bolt" in text and "11 ft-lb" in text


def test_processing_and_fits_follow_each_set_then_comparisons_and_report(plan: Plan) -> None:
    kinds = [s.kind for s in plan.steps]
    assert kinds[-1] == "report"
    first_compare = kinds.index("compare")
    assert all(k == "compare" for k in kinds[first_compare:-1])
    ids = [s.id for s in plan.steps]
    for key in TABLE_5:
        p_idx = ids.index(f"process:k{key:02d}")
        last_trial = max(
            i for i, s in enumerate(plan.steps) if isinstance(s, TrialStep) and s.configuration == key
        )
        assert last_trial < p_idx < ids.index(f"fit:k{key:02d}")


def test_plan_json_contract_shape(plan: Plan) -> None:
    data = json.loads(plan.dumps())
    assert set(data) == {"protocol", "protocol_sha256", "steps"}
    assert data["protocol"] == "knee_phase1" and len(data["protocol_sha256"]) == 64
    trial = next(s for s in data["steps"] if s["kind"] == "trial")
    assert {"id", "kind", "set", "configuration", "run", "trial", "brace", "settings", "trajectory"} <= set(
        trial
    )
    assert isinstance(trial["configuration"], int) and trial["brace"] in ("on", "off")
    # one entry per declared factor: {"level": label, its quantities} (docs/protocol.md)
    assert trial["settings"]["brace_rom"] == {"level": "R3", "range_deg": [0.0, 130.0]}
    assert trial["settings"]["friction"] == {"level": "2", "friction_nm": 3.75, "screw_turns": 0.75}
    assert list(trial["settings"]) == ["brace_rom", "robot_rom", "friction", "stiffness", "speed", "preload"]
    assert [e["type"] for e in trial["device"]] == [
        "rom_stops",
        "coulomb_brake",
        "coulomb_brake",
        "lever_spring",
        "cuff_shift",
    ]
    off = next(s for s in data["steps"] if s["kind"] == "trial" and s["brace"] == "off")
    assert "device" not in off
    assert {"profile", "name", "mean_deg", "amplitude_deg", "period_s", "duration_s"} <= set(
        trial["trajectory"]
    )
    human = next(s for s in data["steps"] if s["kind"] == "trial" and s["trajectory"]["profile"] == "file")
    assert human["trajectory"]["source"].endswith(".csv")
    cal = next(s for s in data["steps"] if s["kind"] == "calibration_check")
    assert cal["when"] in ("before", "after") and "set" in cal


def test_ids_are_unique_and_stable_across_expansions(plan: Plan) -> None:
    ids = [s.id for s in plan.steps]
    assert len(ids) == len(set(ids))
    again = expand(load_protocol(KNEE))
    assert [s.id for s in again.steps] == ids
    assert again.to_json() == plan.to_json()


@settings(max_examples=25, deadline=None)
@given(st.sets(st.integers(min_value=1, max_value=28), min_size=1, max_size=28))
def test_only_keeps_exactly_the_asked_configurations(keys: set[int]) -> None:
    full = _full_plan()
    sub = expand(_loaded(), only=keys)
    sub_trials = [s for s in sub.steps if isinstance(s, TrialStep)]
    assert {t.configuration for t in sub_trials} == keys
    # same ids as in the full plan (resume keys do not depend on --only), same relative order
    full_ids = [s.id for s in full.steps]
    positions = [full_ids.index(s.id) for s in sub.steps]
    assert positions == sorted(positions)
    # every set that has a selected configuration keeps both calibration checks; no other set does
    sets_with = {t.set for t in sub_trials}
    cal_sets = {s.set for s in sub.steps if isinstance(s, CalibrationCheckStep)}
    assert cal_sets == sets_with
    # every brace-on trial has its brace-off twin later in the same set
    for t in sub_trials:
        if t.brace == "on":
            twin = sub.step(t.id.replace(":on:", ":off:"))
            assert isinstance(twin, TrialStep) and twin.set == t.set and twin.twin == t.id
            assert sub.steps.index(twin) > sub.steps.index(t)


_CACHE: dict[str, object] = {}


def _loaded():  # type: ignore[no-untyped-def]
    if "loaded" not in _CACHE:
        _CACHE["loaded"] = load_protocol(KNEE)
    return _CACHE["loaded"]


def _full_plan() -> Plan:
    if "plan" not in _CACHE:
        _CACHE["plan"] = expand(_loaded())  # type: ignore[arg-type]
    return _CACHE["plan"]  # type: ignore[return-value]


def test_robot_time_is_about_the_thesis_campaign(plan: Plan) -> None:
    # 136 trials of ~65 s (plus half-speed ones) and 18 calibration checks: a few hours of robot time
    assert 2.0 * 3600 < plan.robot_time_s < 3.0 * 3600
    assert math.isclose(sum(s.robot_time_s for s in plan.steps), plan.robot_time_s)


def test_a_negative_range_reads_unambiguously_in_the_checklist() -> None:
    """The ankle's stops span -38 to 24 deg: a dash between the ends would print "-38-24 deg"."""
    ankle = REPO / "protocols" / "ankle_phase2.yaml"
    plan = expand(load_protocol(ankle))
    shown = [
        i.split("range_deg = ", 1)[1]
        for c in plan.steps
        if isinstance(c, ChecklistStep)
        for i in c.items
        if "range_deg = " in i
    ]
    assert any(text.startswith("from -38 to 24 deg") for text in shown)
    assert not any("-38-24" in text for text in shown)
