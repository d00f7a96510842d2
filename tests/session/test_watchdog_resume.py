"""A joint that jams during a dry run: the watchdog stops the motion within its declared time and parks the
joint (exit 4), everything finished before stays journaled, every sample sent while stopping is inside the
safety envelope, and `--resume` with the jam removed finishes the campaign, redoing the interrupted trial
exactly once.

The jam is injected by a test fixture into the DAQ simulator only: at the start of one trial, the
simulated brace's range-of-motion stops close around the park angle (stiff stops 2 deg either side), so
the joint no longer follows its command. Nothing of this reaches a hardware rig.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import cast

import h5py
import numpy as np
import pytest

from protocol_runner.commands import resume, run, verify
from protocol_runner.errors import EXIT_STOPPED_BY_CHECK, WatchdogTripped
from protocol_runner.hardware.rig import READ_EVERY_TICKS
from protocol_runner.hardware.simulator.daq import TRANSFER_S, SimulatedRig
from protocol_runner.hardware.stream import STOP, TRAJECTORY
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.stream_check import safety_limits
from protocol_runner.session.journal import inspect_journal
from protocol_runner.session.rigs import SimulatedBench

PROTOCOL = "elbow_example.yaml"  # declares a 15 deg / 1 s watchdog: the elbow is never held
ONLY = [1]
JAMMED = "trial:k01:on:2"  # the second brace-on trial: the calibration check and a trial are finished
JAM_HALF_WIDTH_DEG = 2.0


@pytest.fixture
def jam(monkeypatch: pytest.MonkeyPatch) -> None:
    """Jam the simulated joint at the start of step JAMMED (the simulator's device only)."""
    begin_step = SimulatedBench.begin_step

    def jammed(self: SimulatedBench, step_id: str) -> None:
        begin_step(self, step_id)
        if step_id == JAMMED:
            park = float(self.rig.joints[0].limits.park_angle_deg)
            stops = [park - JAM_HALF_WIDTH_DEG, park + JAM_HALF_WIDTH_DEG]
            cast("SimulatedRig", self.sim).set_device(
                [("jam", "rom_stops", {"range_deg": stops, "stop_stiffness_nm_per_deg": 40.0})]
            )

    monkeypatch.setattr(SimulatedBench, "begin_step", jammed)


def unit_records(session: Path) -> list[str]:
    """The step ids of the journal's unit records, in order (a step journaled twice appears twice)."""
    lines = (session / "journal.jsonl").read_text(encoding="utf-8").splitlines()
    return [r["step_id"] for r in map(json.loads, lines) if r.get("record") == "unit"]


def test_a_jam_stops_the_motion_within_the_declared_time_and_resume_finishes(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, jam: None
) -> None:
    loaded = load_protocol(find_protocol(PROTOCOL))
    rig = loaded.protocol.rig
    watch = rig.watchdog.merged(loaded.protocol.watchdog)
    limits = safety_limits(rig)
    assert (watch.max_tracking_error_deg, watch.max_tracking_error_s) == (15.0, 1.0)
    session = tmp_path / "jammed"

    with pytest.raises(WatchdogTripped) as caught:
        run(PROTOCOL, dry_run=True, session=session, seed=7, yes=True, only=ONLY, realtime=False, quiet=True)
    exc = caught.value
    assert exc.exit_code == EXIT_STOPPED_BY_CHECK == 4
    assert exc.where.startswith(JAMMED) and exc.quantity == "tracking error"
    assert abs(exc.value) > watch.max_tracking_error_deg

    # (1) from the recorded data of the stopped trial: the jam's onset is the first input sample whose
    # tracking error (the angle minus the command delayed by the servo lag) exceeds the limit. The brake
    # (the first sample of the stop) comes once the excursion has lasted the declared time, and at most
    # that plus the watchdog's lateness: it sees the samples when the loop reads them, every
    # READ_EVERY_TICKS ticks on the rig, and in a dry run when the simulated board hands them over (whole
    # transfers of TRANSFER_S of scan time, docs/hardware.md), plus a tick
    (rec,) = exc.partial_recording  # type: ignore[attr-defined]  # one recording per driven joint
    dt = 1.0 / rec.output_rate_hz
    delayed = np.interp(
        rec.input_time_s - rig.time_constant_s, rec.stream_time_s, rec.stream_deg, left=rec.stream_deg[0]
    )
    beyond = np.abs(rec.angle_deg - delayed) > watch.max_tracking_error_deg
    assert beyond.any()
    onset_s = float(rec.input_time_s[np.argmax(beyond)])
    stopping = rec.stream_segment == STOP
    assert stopping.any()
    first_stop = int(np.argmax(stopping))
    brake_s = float(rec.stream_time_s[first_stop])
    lateness_s = TRANSFER_S + (READ_EVERY_TICKS + 2) * dt
    assert onset_s + watch.max_tracking_error_s - 2 * dt <= brake_s
    assert brake_s <= onset_s + watch.max_tracking_error_s + lateness_s
    # the joint was parked in the same loop
    assert rec.stream_deg[-1] == pytest.approx(limits.park_angle_deg)
    assert np.all(rec.stream_segment[first_stop:] == STOP)

    # every sample sent from the last one before the stop to the park is inside range, rate and
    # acceleration (the junction with the trajectory included; at rest once parked)
    sent = np.concatenate([rec.stream_deg[first_stop - 2 :], [rec.stream_deg[-1]]])
    lo, hi = limits.range_deg
    assert np.all((sent >= lo) & (sent <= hi))
    assert np.max(np.abs(np.diff(sent))) / dt <= limits.max_rate_deg_s * (1 + 1e-9)
    assert np.max(np.abs(np.diff(sent, 2))) / dt**2 <= limits.max_accel_deg_s2 * (1 + 1e-9)
    assert rec.stream_segment[first_stop - 1] == TRAJECTORY  # the stop cut the trial's own motion

    # (2) nothing recorded is lost: the steps finished before the jam are journaled, their units intact
    # (--verify), the archive holds them and says why it stopped; the stopped trial is not kept
    finished = dict(inspect_journal(session / "journal.jsonl").units)
    assert set(finished) == {"cal:factorial:before", "check:factorial:k01", "trial:k01:on:1"}
    assert verify(session) == 0
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "aborted"
        trials = f["configurations/config_01/trials"]
        assert "1" in trials and "2" not in trials
        events = [json.loads(e) for e in f["session/events"].asstr()[:]]
        assert events[-1]["kind"] == "aborted" and "watchdog" in events[-1]["detail"]

    # (3) the jam removed, --resume completes the campaign
    monkeypatch.undo()
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    done = inspect_journal(session / "journal.jsonl").units
    plan = expand(loaded, only=ONLY)
    assert {s.id for s in plan.steps if s.kind != "report"} <= set(done)  # every step, the analyses too
    records = unit_records(session)
    assert records.count(JAMMED) == 1  # the interrupted trial, redone once
    for step_id, unit in finished.items():  # the finished steps were not redone
        assert records.count(step_id) == 1 and done[step_id].sha256 == unit.sha256
    assert verify(session) == 0
    assert (session / "report.html").is_file()
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "complete"
        assert set(f["configurations/config_01/trials"]) == {"1", "2", "3"}
        kinds = [json.loads(e)["kind"] for e in f["session/events"].asstr()[:]]
        assert kinds.index("aborted") < kinds.index("resumed") and kinds[-1] == "finished"
