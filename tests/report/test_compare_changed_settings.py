"""`--compare` names a changed motion among a pair's changed settings: configurations match on the
trajectory's name, so two sessions whose `sine` spans another range or speed still pair, and the pair says
how the motion differs (the trial's archived `trajectory` attribute, the plan's resolved fields)."""

from __future__ import annotations

import json
from pathlib import Path

import h5py
import pytest

from protocol_runner.report.compare import compare_archives
from protocol_runner.report.load import load_report_data
from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

SINE = {
    "profile": "sinusoid",
    "name": "sine",
    "mean_deg": 50.0,
    "amplitude_deg": 25.0,
    "period_s": 5.23599,
    "range_deg": [25.0, 75.0],
    "speed_deg_s": 30.0,
    "periods": 3.0,
    "duration_s": 15.708,
}


def _archive(folder: Path, trajectory: dict[str, object] | None) -> Path:
    folder.mkdir()
    configs = [ConfigSpec(key=k, energy_j=2.0, n_trials=3, energy_spread=0.02) for k in (4, 5)]
    path = write_archive(folder / "archive.h5", ArchiveSpec(configs=configs, duration_s=17.0, seed=3))
    if trajectory is not None:
        with h5py.File(path, "r+") as f:
            for name in f["configurations"]:
                for trial in f[f"configurations/{name}/trials"].values():
                    for side in ("brace_on", "brace_off"):
                        trial[side].attrs["trajectory"] = json.dumps(trajectory)
    return path


@pytest.fixture(scope="module")
def roots(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("changed")


def test_the_loaded_configuration_carries_its_trials_trajectory(roots: Path) -> None:
    data = load_report_data(_archive(roots / "loaded", SINE))
    assert {json.loads(c.trajectory_json)["range_deg"][1] for c in data.configurations} == {75.0}


def test_a_narrower_slower_sine_is_named_among_the_changed_settings(roots: Path) -> None:
    narrow = SINE | {"range_deg": [35.0, 65.0], "speed_deg_s": 15.0, "amplitude_deg": 15.0}
    result = compare_archives(_archive(roots / "a", SINE), _archive(roots / "b", narrow))
    assert len(result.pairs) == 2
    for pair in result.pairs:
        changed = {name: (a, b) for name, a, b in pair.changed}
        assert changed["trajectory.range_deg"] == ("[25, 75]", "[35, 65]")
        assert changed["trajectory.speed_deg_s"] == ("30", "15")
        assert changed["trajectory.amplitude_deg"] == ("25", "15")
        assert "trajectory.periods" not in changed and "trajectory.name" not in changed


def test_the_same_motion_changes_nothing_and_an_archive_without_the_attribute_reads(roots: Path) -> None:
    same = compare_archives(_archive(roots / "c", SINE), _archive(roots / "d", SINE))
    assert all(not any(n.startswith("trajectory.") for n, _, _ in p.changed) for p in same.pairs)
    old = compare_archives(_archive(roots / "e", None), _archive(roots / "f", None))
    assert all(p.changed == () for p in old.pairs)


def test_a_multi_joint_motion_is_named_by_joint(roots: Path) -> None:
    a = {"hip_flexion": SINE, "knee_flexion": SINE}
    b = {"hip_flexion": SINE, "knee_flexion": SINE | {"periods": 6.0}}
    result = compare_archives(_archive(roots / "g", a), _archive(roots / "h", b))
    for pair in result.pairs:
        assert [(n, x, y) for n, x, y in pair.changed if n.startswith("trajectory.")] == [
            ("trajectory.knee_flexion.periods", "3", "6")
        ]


def test_sessions_with_nothing_in_common_are_named_in_the_order_given(roots: Path) -> None:
    from protocol_runner.errors import InvalidInput

    a = _archive(roots / "named_a", SINE)
    b = _archive(roots / "named_b", None)
    with h5py.File(b, "r+") as f:
        for group in f["configurations"].values():
            group.attrs["trajectory_name"] = "triangle"  # another motion: no configuration pairs
    with pytest.raises(InvalidInput) as caught:
        compare_archives(a, b)
    assert caught.value.message.startswith(f"{a} and {b} have no configuration with the same settings")
