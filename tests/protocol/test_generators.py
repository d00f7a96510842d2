"""Matrix generators (protocol/generators.py): what each produces, in which order, with which keys."""

from __future__ import annotations

import itertools
from pathlib import Path

from protocol_runner.protocol.loader import load_protocol
from protocol_runner.protocol.resolve import resolve_settings

REPO = Path(__file__).resolve().parents[2]
ANKLE = REPO / "protocols" / "ankle_phase2.yaml"
KNEE = REPO / "protocols" / "knee_phase1.yaml"


def test_full_factorial_is_the_cross_product_last_factor_fastest_keys_in_order() -> None:
    p = load_protocol(ANKLE).protocol
    rows = [(s.name, c) for s, c in p.configurations()]
    assert len(rows) == 3 * 3 * 2 == 18
    assert [c.key for _, c in rows] == list(range(1, 19)) and [c.run for _, c in rows] == list(range(1, 19))
    expected = list(itertools.product(["none", "soft", "stiff"], ["b0", "b1", "b2"], ["slow", "fast"]))
    got = [(c.levels["bungee"], c.levels["brake"], c.levels["speed"]) for _, c in rows]
    assert got == expected
    # trajectory_by_level: slow -> triangle, fast -> sinusoid
    assert all(
        p.profile_of(c) == ("triangle" if c.levels["speed"] == "slow" else "sinusoid") for _, c in rows
    )
    assert all(c.trials == 3 for _, c in rows)


def _with_set(tmp_path: Path, set_yaml: str) -> Path:
    text = KNEE.read_text(encoding="utf-8").replace(
        "sets:                                # executed", set_yaml + "\n  # executed", 1
    )
    for sub in ("calibration", "trajectories"):
        (tmp_path / sub).mkdir()
        for f in (REPO / "protocols" / sub).iterdir():
            (tmp_path / sub / f.name).write_bytes(f.read_bytes())
    path = tmp_path / "knee_ofat.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_one_factor_at_a_time_varies_each_factor_alone_around_the_baseline(tmp_path: Path) -> None:
    ofat = """sets:
  - name: ofat
    condition: One factor at a time
    one_factor_at_a_time:
      baseline: {brace_rom: R3, robot_rom: Rr3, friction: "2", stiffness: K2, speed: Full, preload: Center}
      vary: {friction: ["0", "2", "3"], stiffness: [K1, K3]}
      trajectory: sine
      trials: 1"""
    p = load_protocol(_with_set(tmp_path, ofat)).protocol
    generated = p.sets[0].configurations
    # baseline, then friction 0 and 3 (2 is the baseline's), then K1 and K3
    assert [(c.levels["friction"], c.levels["stiffness"]) for c in generated] == [
        ("2", "K2"),
        ("0", "K2"),
        ("3", "K2"),
        ("2", "K1"),
        ("2", "K3"),
    ]
    # keys and runs continue after the largest of the explicit rows (28)
    assert [c.key for c in generated] == [29, 30, 31, 32, 33] and [c.run for c in generated] == [
        29,
        30,
        31,
        32,
        33,
    ]
    st = resolve_settings(p, generated[1])
    assert st.quantity("friction", "friction_nm") == 0.0
    assert dict(st.device[1].params)["torque_nm"] == 0.0  # the brake element follows the varied level
