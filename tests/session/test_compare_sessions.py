"""`--compare`: two dry runs side by side and `--export` of a real session.

Three short dry runs of the friction set (configurations 4-7) of a copy of knee_phase1 with fewer periods
and no fits (seconds each): baseline (seed 0), a second seed, and a stiffer brake (levels 1-3 at 1.6 times
their torque).
"""

from __future__ import annotations

import csv
import re
import shutil
from pathlib import Path

import pytest
import yaml

from protocol_runner.cli import main
from protocol_runner.commands import run
from protocol_runner.report.compare import compare_archives

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
FRICTION = [4, 5, 6, 7]

pytestmark = pytest.mark.slow


def _protocol(folder: Path, *, brake_factor: float = 1.0) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for sub in ("calibration", "trajectories"):
        shutil.copytree(PROTOCOLS / sub, folder / sub, dirs_exist_ok=True)
    doc = yaml.safe_load((PROTOCOLS / "knee_phase1.yaml").read_text(encoding="utf-8"))
    doc["trajectories"]["sine"]["periods"] = 3
    doc["fits"] = {"spring": {"enabled": False}, "bouc_wen": {"enabled": False}}
    for level in doc["factors"]["friction"].values():
        if "friction_nm" in level:
            level["friction_nm"] = round(level["friction_nm"] * brake_factor, 4)
    path = folder / "knee_fast.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    return path


def _dry(protocol: Path, session: Path, seed: int) -> Path:
    code = run(
        str(protocol),
        dry_run=True,
        session=session,
        seed=seed,
        yes=True,
        only=FRICTION,
        realtime=False,
        quiet=True,
    )
    assert code == 0
    return session


@pytest.fixture(scope="module")
def sessions(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("compare")
    base = _protocol(root / "base")
    stiff = _protocol(root / "stiff", brake_factor=1.6)
    return {
        "a": _dry(base, root / "a", seed=0),
        "b": _dry(base, root / "b", seed=1),
        "stiff": _dry(stiff, root / "s", seed=2),
    }


def test_two_seeds_of_one_campaign_show_no_significant_difference(sessions: dict[str, Path]) -> None:
    result = compare_archives(sessions["a"] / "archive.h5", sessions["b"] / "archive.h5")
    assert [(p.a.key, p.b.key) for p in result.pairs] == [(k, k) for k in FRICTION]
    same = [p for p in result.pairs if not p.significant]
    assert len(same) >= 0.9 * len(result.pairs)


def test_a_stiffer_brake_makes_its_friction_configurations_differ(
    sessions: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "compare.html"
    assert main(["--compare", str(sessions["a"]), str(sessions["stiff"]), "--output", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "4 matched configurations" in printed
    html = out.read_text(encoding="utf-8")
    flags = dict(re.findall(r'data-a="(\d+)" data-b="\d+" data-significant="(yes|no)"', html))
    # no brake pads (level 0) is untouched; levels 1-3 lose more energy with the stiffer brake
    assert flags == {"4": "no", "5": "yes", "6": "yes", "7": "yes"}
    energy = dict(
        re.findall(
            r'data-a="(\d+)" data-b="\d+" data-significant="(?:yes|no)"\s+data-energy="(yes|no)"', html
        )
    )
    assert energy == flags  # the brake changes the energy lost per cycle
    result = compare_archives(sessions["a"] / "archive.h5", sessions["stiff"] / "archive.h5")
    for p in result.pairs[1:]:
        assert p.energy.low > 0  # B (stiffer) minus A: more energy lost per cycle
        assert (
            "friction.friction_nm",
            f"{p.a.quantity('friction', 'friction_nm'):g}",
            f"{p.b.quantity('friction', 'friction_nm'):g}",
        ) in p.changed
    assert html.count("<img ") == 4


def test_sessions_without_a_common_configuration_are_incomparable(
    sessions: dict[str, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    other = tmp_path / "other"
    other.mkdir()
    # the small synthetic layout would match; an archive with one configuration of another set must not
    from tests.report.report_archive_builder import ArchiveSpec, ConfigSpec, write_archive

    archive = write_archive(other / "archive.h5", ArchiveSpec(configs=[ConfigSpec(key=12)], duration_s=17.0))
    assert main(["--compare", str(sessions["a"]), str(archive), "--output", str(tmp_path / "c.html")]) == 2
    err = capsys.readouterr().err
    assert "no configuration with the same settings" in err and "Traceback" not in err
    assert not (tmp_path / "c.html").exists()


def test_export_of_a_dry_run_fills_every_cycle(sessions: dict[str, Path], tmp_path: Path) -> None:
    assert main(["--export", str(sessions["a"]), "--output", str(tmp_path)]) == 0
    with (tmp_path / "cycles.csv").open(encoding="utf-8", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {int(r["configuration"]) for r in rows} == set(FRICTION)
    assert all(r["angle_min_deg"] and r["angle_max_deg"] and r["torque_peak_nm"] for r in rows)
    assert all(float(r["angle_max_deg"]) - float(r["angle_min_deg"]) > 50 for r in rows)


def test_a_finished_session_records_its_verdicts_and_still_verifies(sessions: dict[str, Path]) -> None:
    import h5py

    from protocol_runner.archive.verify import verify_path

    with h5py.File(sessions["a"] / "archive.h5", "r") as h5:
        assert h5["expectations/energy_friction"].attrs["verdict"] == "met"
        assert h5["expectations/friction_range"].attrs["verdict"] in ("met", "not met")
        assert h5["expectations/speed_energy"].attrs["verdict"] == "not evaluable"  # not run (--only)
    verdict = verify_path(sessions["a"] / "archive.h5")
    assert not verdict.problems, verdict.lines
