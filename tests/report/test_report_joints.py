"""The report of several joints driven together (a dry run of protocols/leg_phase2.yaml, one configuration,
hip, knee and ankle): trials and cycles counted per joint and for all joints together, every figure drawn
for every joint, every joint's fits shown; and a single joint's report without any of it."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from matplotlib.figure import Figure

from protocol_runner.commands import run
from protocol_runner.report import figures
from protocol_runner.report.figure_plan import figure_jobs
from protocol_runner.report.load import load_report_data

REPO = Path(__file__).resolve().parents[2]
JOINTS = ("hip_flexion", "knee_flexion", "ankle_flexion")
FITTED = ("knee_flexion", "ankle_flexion")  # the hip carries no element: it is not fitted


@pytest.fixture(scope="module")
def leg(tmp_path_factory: pytest.TempPathFactory) -> Path:
    session = tmp_path_factory.mktemp("leg") / "s"
    code = run(
        str(REPO / "protocols" / "leg_phase2.yaml"),
        dry_run=True,
        session=session,
        seed=11,
        yes=True,
        only=[2],
        realtime=False,
        quiet=True,
    )
    assert code == 0
    return session


def _drawn(monkeypatch: pytest.MonkeyPatch, draw: Callable[[], str]) -> Figure:
    """The matplotlib Figure a figure function draws (captured before it becomes a PNG)."""
    captured: list[Figure] = []
    real = figures.to_data_uri

    def keep(fig: Figure) -> str:
        captured.append(fig)
        return real(fig)

    monkeypatch.setattr(figures, "to_data_uri", keep)
    draw()
    return captured[-1]


def _figure(leg: Path, monkeypatch: pytest.MonkeyPatch, figure_id: str) -> Figure:
    data = load_report_data(leg / "archive.h5")
    (job,) = [(kind, args) for fid, kind, args in figure_jobs(data) if fid == figure_id]
    return _drawn(monkeypatch, lambda: figures.DRAW[job[0]](*job[1]))


def _cell_numbers(row: str) -> list[str]:
    return re.findall(r'<td class="num">([^<]*)</td>', row)


def test_the_report_holds_each_joint_of_each_configuration_and_their_total(leg: Path) -> None:
    data = load_report_data(leg / "archive.h5")
    assert data.joints == JOINTS and data.multi_joint and data.keys == (2,)
    assert [(c.key, c.joint) for c in data.configurations] == [(2, j) for j in JOINTS]
    with h5py.File(leg / "archive.h5", "r") as f:
        cfg = f["configurations/config_02"]
        for joint in JOINTS:
            part = data.configuration(2, joint)
            assert part is not None and len(part.trials) == 3
            assert np.array_equal(part.energy_loss_j, cfg[f"joints/{joint}/energy_loss_j"][:])
            assert all(t.processed is not None and t.processed.angle_deg.size for t in part.trials)
            first = part.trials[0].brace_on
            assert first is not None and first.angle_deg.size == first.time_s.size > 0  # its own angle
        total = data.total(2)
        assert total is not None and np.array_equal(total.energy_loss_j, cfg["total_energy_loss_j"][:])


def test_the_summary_counts_trials_and_cycles_per_joint_and_all_joints_together(leg: Path) -> None:
    html = (leg / "report.html").read_text(encoding="utf-8")
    with h5py.File(leg / "archive.h5", "r") as f:
        cfg = f["configurations/config_02"]
        cycles = {j: cfg[f"joints/{j}/energy_loss_j"].size for j in JOINTS}
        cycles["all joints"] = cfg["total_energy_loss_j"].size
    table = html.split('id="summary-joints"', 1)[1].split("</table>", 1)[0]
    for joint, n in cycles.items():
        row = table.split(f'data-joint="{joint}"', 1)[1].split("</tr>", 1)[0]
        assert _cell_numbers(row) == ["3", str(n)]  # 3 trials analysed, its own cycles
    lead = html.split('<section id="summary">', 1)[1].split("</p>", 1)[0]
    assert f"1 configuration,\n3 trials, {cycles['all joints']} cycles of all\n3 joints together" in lead
    for joint in (*JOINTS, "all joints"):  # the headline: a row per joint, and the total
        row = html.split(f'id="headline-2-{joint.replace("_", "-").replace(" ", "-")}"', 1)[1].split("</tr>")[
            0
        ]
        assert _cell_numbers(row)[:2] == ["3 of 3", str(cycles[joint])]
        assert "—" not in _cell_numbers(row)[2]  # an energy per cycle for every joint
    assert "Figure not drawn" not in html


def test_every_configuration_figure_has_a_panel_per_joint_over_its_data(
    leg: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = load_report_data(leg / "archive.h5")
    loops = _figure(leg, monkeypatch, "fig-config-2-hysteresis")
    assert [ax.get_title() for ax in loops.axes] == list(JOINTS)
    for ax, joint in zip(loops.axes, JOINTS, strict=True):
        part = data.configuration(2, joint)
        assert part is not None
        fit = 1 if part.element_fit is not None and part.element_fit.drawable else 0
        assert len(ax.get_lines()) == 3 + fit  # each trial's loop, and the elastic model where fitted
        x = np.concatenate([line.get_xdata() for line in ax.get_lines()[:3]])
        assert x.min() == pytest.approx(part.angle_min_deg, abs=1.0)  # this joint's own angles
        assert x.max() == pytest.approx(part.angle_max_deg, abs=1.0)
    time = _figure(leg, monkeypatch, "fig-config-2-time")
    assert len(time.axes) == 2 * len(JOINTS)
    for k, joint in enumerate(JOINTS):
        angle, torque = time.axes[2 * k], time.axes[2 * k + 1]
        assert angle.get_title().startswith(f"{joint}: angle") and torque.get_title().startswith(joint)
        on = data.configuration(2, joint).trials[0].brace_on  # type: ignore[union-attr]
        assert on is not None
        assert np.array_equal(angle.get_lines()[0].get_ydata(), on.angle_deg)
        assert len(angle.get_lines()) == 3 and len(torque.get_lines()) == 2  # on, off (and the command)
    energy = _figure(leg, monkeypatch, "fig-config-2-energy")
    for ax, joint in zip(energy.axes, JOINTS, strict=True):
        points = sum(len(line.get_xdata()) for line in ax.get_lines() if line.get_marker() == "o")
        assert points == data.configuration(2, joint).energy_loss_j.size  # type: ignore[union-attr]
    phase = _figure(leg, monkeypatch, "fig-config-2-phase")
    (ax,) = phase.axes
    assert ax.get_xlabel().startswith(JOINTS[0]) and ax.get_ylabel().startswith(JOINTS[1])
    measured = ax.get_lines()[0]
    assert len(measured.get_xdata()) == len(measured.get_ydata()) > 100


def test_the_models_section_shows_every_fitted_joints_fits(
    leg: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    html = (leg / "report.html").read_text(encoding="utf-8")
    models = html.split('<section id="models">', 1)[1].split('<section id="test-matrix">', 1)[0]
    assert "No element fit" not in models and "No Bouc-Wen fit" not in models
    for joint in FITTED:
        assert f'id="elements-2-{joint.replace("_", "-")}"' in models
        assert models.count(f"<td>{joint}</td>") >= 2  # the element table and the Bouc-Wen tables
    bouc_wen = _figure(leg, monkeypatch, "fig-config-2-boucwen")
    assert [ax.get_title() for ax in bouc_wen.axes] == [
        f"{j}: {panel}" for j in FITTED for panel in ("loop", "per sample")
    ]
    for ax in bouc_wen.axes:
        data_line, model_line = ax.get_lines()
        assert len(data_line.get_xdata()) == len(model_line.get_xdata()) > 100


def test_calibration_has_a_row_and_a_panel_per_joint(leg: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    fig = _figure(leg, monkeypatch, "fig-calibration-leg")
    assert [ax.get_title() for ax in fig.axes] == list(JOINTS)
    for ax in fig.axes:
        assert {line.get_label() for line in ax.get_lines()} >= {"before: pass", "after: pass"}
    html = (leg / "report.html").read_text(encoding="utf-8")
    calibration = html.split('<section id="calibration">', 1)[1].split("</table>", 1)[0]
    assert all(calibration.count(f"<td>{joint}</td>") == 2 for joint in JOINTS)  # before and after


def test_a_single_joint_report_has_no_joint_columns(tmp_path: Path) -> None:
    session = tmp_path / "ankle"
    code = run(
        str(REPO / "protocols" / "ankle_phase2.yaml"),
        dry_run=True,
        session=session,
        seed=1,
        yes=True,
        only=[2],
        realtime=False,
        quiet=True,
    )
    assert code == 0
    data = load_report_data(session / "archive.h5")
    assert len(data.joints) == 1 and not data.multi_joint and data.totals == ()
    html = (session / "report.html").read_text(encoding="utf-8")
    assert 'id="headline-2"' in html and "data-joint" not in html and "summary-joints" not in html
    assert "<th>Joint</th>" not in html and "all joints" not in html
