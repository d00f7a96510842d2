"""`run-protocol --plan FILE --power SESSION` / `--power-cv CV`: the trials per configuration each declared
expectation needs for 80 % power at Holm's most stringent level, checked against a direct noncentral-t
calculation, and the flags' mistakes refused with exit 2.

SESSION is a seeded knee_phase1 dry run: the equivalence baseline's when this machine has it, else one
made here (fits off, 3 periods: the spread of the trials is what matters, not the fits).
"""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy import stats

from protocol_runner.cli import main
from protocol_runner.report.headline import trial_values
from protocol_runner.report.load import load_report_data

from .short_knee import short_knee_session

PROTOCOLS = Path(__file__).resolve().parents[1] / "protocols"
KNEE_IDS = [
    e["id"] for e in yaml.safe_load((PROTOCOLS / "knee_phase1.yaml").read_text("utf-8"))["expectations"]
]
ALPHA_EACH = 0.05 / len(KNEE_IDS)

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def knee_session(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return short_knee_session(tmp_path_factory.mktemp("knee"), None)


@pytest.fixture(scope="module")
def power_output(knee_session: Path) -> str:
    import contextlib
    import io

    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["--plan", "knee_phase1.yaml", "--power", str(knee_session)]) == 0
    return out.getvalue()


def _rows(text: str) -> dict[str, tuple[str, int, str]]:
    """expectation id -> (needed as printed, planned, outcome)."""
    rows: dict[str, tuple[str, int, str]] = {}
    for line in text.splitlines():
        m = re.match(r"^(\w+)\s+(\d+|-|>\d+)\s+(\d+)\s+(decides|CANNOT DECIDE|cannot plan)\s", line)
        if m:
            rows[m.group(1)] = (m.group(2), int(m.group(3)), m.group(4))
    return rows


def _one_sided_welch_power(effect: float, sd_a: float, sd_b: float, n: int, alpha: float) -> float:
    """By hand: Welch-Satterthwaite df of the SDs with n trials each, noncentral t (scipy.stats.nct)."""
    va, vb = sd_a**2 / n, sd_b**2 / n
    dof = (va + vb) ** 2 / (va**2 / (n - 1) + vb**2 / (n - 1))
    return float(stats.nct.sf(stats.t.ppf(1 - alpha, dof), dof, effect / math.sqrt(va + vb)))


def test_every_knee_expectation_gets_a_trial_count(power_output: str) -> None:
    rows = _rows(power_output)
    assert list(rows) == KNEE_IDS
    assert all(needed.isdigit() for needed, _, _ in rows.values())
    assert all(planned == 3 for _, planned, _ in rows.values())  # knee_phase1 runs 3 trials per configuration
    assert f"alpha/m = 0.05/{len(KNEE_IDS)}" in power_output and "Holm" in power_output


def test_the_count_is_the_smallest_with_80_percent_power_by_a_direct_calculation(
    knee_session: Path, power_output: str
) -> None:
    # speed_energy: energy per cycle of 11 (half speed) minus 10 (full speed) > 0, one-sided Welch
    data = load_report_data(knee_session, workers=1)
    a = np.asarray(trial_values(data.configuration(10), "energy_per_cycle"))  # type: ignore[arg-type]
    b = np.asarray(trial_values(data.configuration(11), "energy_per_cycle"))  # type: ignore[arg-type]
    effect, sd_a, sd_b = b.mean() - a.mean(), a.std(ddof=1), b.std(ddof=1)
    assert effect > 0
    n = int(_rows(power_output)["speed_energy"][0])
    assert _one_sided_welch_power(effect, sd_a, sd_b, n, ALPHA_EACH) >= 0.8
    if n > 2:
        assert _one_sided_welch_power(effect, sd_a, sd_b, n - 1, ALPHA_EACH) < 0.8


def test_the_plan_names_the_expectations_its_trials_cannot_decide(power_output: str) -> None:
    rows = _rows(power_output)
    short = [i for i, (needed, planned, _) in rows.items() if int(needed) > planned]
    decided = [i for i, (needed, planned, _) in rows.items() if int(needed) <= planned]
    assert all(rows[i][2] == "CANNOT DECIDE" for i in short)
    assert all(rows[i][2] == "decides" for i in decided)
    assert f"cannot decide {len(short)} of {len(KNEE_IDS)} expectations" in power_output
    assert ", ".join(short) in power_output


def test_a_cv_alone_plans_a_5_percent_difference_at_5_percent_cv(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["--plan", "knee_phase1.yaml", "--power-cv", "0.05"]) == 0
    rows = _rows(capsys.readouterr().out)
    assert list(rows) == KNEE_IDS
    # one part, d = 1 (both SDs 0.05 of the level, effect 0.05 of it), one-sided at alpha/18
    n = int(rows["speed_energy"][0])
    assert _one_sided_welch_power(0.05, 0.05, 0.05, n, ALPHA_EACH) >= 0.8
    assert _one_sided_welch_power(0.05, 0.05, 0.05, n - 1, ALPHA_EACH) < 0.8
    # an equivalence margin in J cannot be scaled by a CV without a level: said, not guessed
    assert rows["energy_springs"][2] == "cannot plan"


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["--power", "x"], "--power does not apply to a run (PROTOCOL): it goes with --plan"),
        (["--report", "x.h5", "--power-cv", "0.05"], "--power-cv does not apply to --report"),
        (["--plan", "knee_phase1.yaml", "--power", "x", "--power-cv", "0.05"], "give one"),
        (["--plan", "knee_phase1.yaml", "--power-cv", "0"], "--power-cv 0: give a fraction"),
        (["--plan", "knee_phase1.yaml", "--power-cv", "-0.1"], "--power-cv -0.1: give a fraction"),
        (["--plan", "knee_phase1.yaml", "--power-cv", "5"], "--power-cv 5: give a fraction"),
        (["--plan", "knee_phase1.yaml", "--power-cv", "nan"], "--power-cv nan: give a fraction"),
        (["--plan", "knee_phase1.yaml", "--power-effect", "0.05"], "add --power or --power-cv"),
        (["--plan", "knee_phase1.yaml", "--power-cv", "0.05", "--json"], "drop --json"),
    ],
)
def test_flag_mistakes_are_refused_with_exit_2(
    argv: list[str], said: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["knee_phase1.yaml", *argv] if argv[0] == "--power" else argv) == 2
    err = capsys.readouterr().err
    assert said in err and "Traceback" not in err


def test_a_session_that_is_not_an_archive_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    not_hdf5 = tmp_path / "archive.h5"
    not_hdf5.write_text("not an archive", encoding="utf-8")
    assert main(["--plan", "knee_phase1.yaml", "--power", str(not_hdf5)]) == 2
    assert "not an HDF5 file" in capsys.readouterr().err
    assert main(["--plan", "knee_phase1.yaml", "--power", str(tmp_path / "none")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_a_session_of_another_protocol_is_refused(
    knee_session: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--plan", "elbow_example.yaml", "--power", str(knee_session)]) == 2
    err = capsys.readouterr().err
    assert "an archive of protocol 'knee_phase1', not of 'elbow_example'" in err
    assert "Traceback" not in err
