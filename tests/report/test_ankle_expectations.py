"""ankle_phase2's declared expectations, decided by a dry run of the ankle campaign.

The ankle declares physical statements of its brace: the bungee's stiffness steepens the torque-angle
slope; the brake adds a loss that grows with its level at each speed and is the same at both speeds (per
cycle within 0.7 J, per degree of range within 0.005 J/deg). One dry run of a copy of ankle_phase2 with
shorter motions and no model fit, restricted to the configurations those statements name (no bungee and
the no-brake column of the soft and stiff sets), decides them; in a dry run the report labels them as
findings the simulated rig reproduces by construction, and its generated text speaks of the ankle only.
"""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml

from protocol_runner.commands import run
from protocol_runner.report.evaluate import TUNED_LABEL

PROTOCOLS = Path(__file__).resolve().parents[2] / "protocols"
ONLY = [1, 2, 3, 4, 5, 6, 7, 8, 13, 14]
PHYSICAL = {
    "brake_energy_slow",
    "brake_energy_fast",
    "brake_loss_speed_free",
    "brake_loss_per_degree",
    "bungee_slope_slow",
    "bungee_slope_fast",
}

pytestmark = pytest.mark.slow


def test_the_ankle_declares_its_physical_statements_as_simulator_reproduced() -> None:
    doc = yaml.safe_load((PROTOCOLS / "ankle_phase2.yaml").read_text(encoding="utf-8"))
    by_id = {e["id"]: e for e in doc["expectations"]}
    assert set(by_id) >= PHYSICAL
    assert all(by_id[i].get("simulator_tuned") is True for i in PHYSICAL)
    same = by_id["brake_loss_speed_free"]
    # (b2 slow - b0 slow) - (b2 fast - b0 fast): keys 5, 1 (slow) and 6, 2 (fast) of the no-bungee set
    assert (same["relation"], same["configurations"], same["baseline"]) == ("equal", [5], [1])
    assert (same["than"], same["than_baseline"]) == ([6], [2])


@pytest.fixture(scope="module")
def ankle_report(tmp_path_factory: pytest.TempPathFactory) -> str:
    root = tmp_path_factory.mktemp("ankle")
    folder = root / "protocol"
    folder.mkdir()
    doc = yaml.safe_load((PROTOCOLS / "ankle_phase2.yaml").read_text(encoding="utf-8"))
    doc["trajectories"]["tri"]["cycles"] = 3
    doc["trajectories"]["sine"]["periods"] = 4
    doc["fits"] = {"bouc_wen": {"enabled": False}}
    for sub in ("calibration", "trajectories"):
        if (PROTOCOLS / sub).is_dir():
            shutil.copytree(PROTOCOLS / sub, folder / sub)
    path = folder / "ankle_phase2.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")
    session = root / "session"
    code = run(
        str(path), dry_run=True, session=session, seed=3, yes=True, only=ONLY, realtime=False, quiet=True
    )
    assert code == 0
    return (session / "report.html").read_text(encoding="utf-8")


def _rows(html: str) -> dict[str, tuple[str, str]]:
    rows = re.findall(
        r'<tr class="expectation"[^>]*data-expectation="([^"]+)" data-verdict="([^"]+)">(.*?)</tr>',
        html,
        re.S,
    )
    return {i: (v, body) for i, v, body in rows}


# the two equivalence statements cannot be shown with 3 trials a side once the simulator's between-trial
# spread (robot friction CV 5 %, device 3 %) is on: the 90 % interval of a difference of differences of four
# 3-trial means is wider than the +-0.7 J (+-0.005 J/deg) margin even when the true difference is nil
UNDECIDABLE_WITH_3_TRIALS = {"brake_loss_speed_free", "brake_loss_per_degree"}


def test_a_dry_run_meets_the_brake_and_bungee_statements_with_the_honesty_label(ankle_report: str) -> None:
    rows = _rows(ankle_report)
    expected = {i: "not-met" if i in UNDECIDABLE_WITH_3_TRIALS else "met" for i in PHYSICAL}
    assert {i: rows[i][0] for i in PHYSICAL} == expected
    for i in PHYSICAL - UNDECIDABLE_WITH_3_TRIALS:
        verdict_cell = re.findall(r"<td class=\"ok\">(.*?)</td>", rows[i][1], re.S)
        assert verdict_cell and TUNED_LABEL in verdict_cell[-1]  # beside the verdict
    for i in UNDECIDABLE_WITH_3_TRIALS:
        assert TUNED_LABEL in rows[i][1]
    added = rows["brake_loss_speed_free"][1]
    assert "(5 minus 1) minus (6 minus 2)" in added and "Welch-Satterthwaite interval" in added
    # the stops statement names configurations 11 and 17, not run here
    assert rows["stops_hold"][0] == "not-evaluable"
    assert TUNED_LABEL not in rows["stops_hold"][1]


def test_the_ankle_report_text_has_no_knee_wording(ankle_report: str) -> None:
    text = re.sub(r"<pre[^>]*>.*?</pre>", "", ankle_report, flags=re.S)  # the protocol as run is quoted
    text = re.sub(r"<[^>]+>", " ", text)
    for word in ("knee", "brace ROM", "brace_rom", "friction set", "spring", "K2", "Chapter 5", "EMU"):
        assert word not in text, word
