"""A dry run watched through `/events`: the messages arrive in order, name the right steps, and carry the
motion; `/status` tells the same; watching changes nothing that is recorded."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from protocol_runner.commands import resume, run
from protocol_runner.monitor.service import Monitor
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.protocol.plan import expand
from protocol_runner.protocol.plan_steps import Plan

from ..session.conftest import ONLY, SEED, assert_same_data
from .sse import Stream, status

ROBOT_KINDS = ("calibration_check", "operator_checklist", "trial")


@dataclass
class Watched:
    code: int
    session: Path
    said: list[str]
    messages: list[dict[str, Any]]
    status: dict[str, Any]
    plan: Plan
    lost: int  # samples messages discarded + points trimmed from bursts (a starved pump, simulated time)


def _watch(session: Path, action: Any) -> tuple[int, list[str], list[dict[str, Any]], dict[str, Any], int]:
    said: list[str] = []
    with Monitor.open("127.0.0.1:0", say=said.append) as live:
        stream = Stream("127.0.0.1", live.port)
        stream.wait_for("hello")
        code = action(live)
        delivered = live.bus.flush(30)  # what the session published: /status shows it
        assert delivered, "the monitor did not deliver what the session published"
        after = status(f"http://127.0.0.1:{live.port}/")
    assert stream.closed.wait(10), "the stream did not end with the monitor"
    stream.close()
    return code, said, stream.messages, after, live.bus.dropped_samples + live.bus.trimmed_points


@pytest.fixture(scope="module")
def watched(tmp_path_factory: pytest.TempPathFactory) -> Watched:
    session = tmp_path_factory.mktemp("monitor") / "session"

    def action(live: Monitor) -> int:
        return run(
            "knee_phase1.yaml",
            dry_run=True,
            session=session,
            seed=SEED,
            yes=True,
            only=ONLY,
            realtime=False,
            quiet=True,
            monitor=live,
        )

    code, said, messages, after, lost = _watch(session, action)
    plan = expand(load_protocol(find_protocol("knee_phase1.yaml")), only=ONLY)
    return Watched(code, session, said, messages, after, plan, lost)


def of(w: Watched, kind: str) -> list[dict[str, Any]]:
    return [m for m in w.messages if m["type"] == kind]


def test_the_run_completes_and_the_url_is_announced_with_its_token(watched: Watched) -> None:
    assert watched.code == 0
    assert re.match(
        r"monitor: http://127\.0\.0\.1:\d+/\?token=[\w-]{20,} \(read-only; this machine only", watched.said[0]
    )
    assert watched.said[0].count("?token=") == 1  # printed once; on loopback the stream was read without it


def test_stream_opens_with_hello_and_ends_with_session_end(watched: Watched) -> None:
    assert watched.messages[0]["type"] == "hello"
    end = watched.messages[-1]
    assert end["type"] == "session_end"
    assert (end["status"], end["exit_code"]) == ("complete", 0)
    numbered = [m["seq"] for m in watched.messages if "seq" in m]
    assert numbered == sorted(set(numbered)), "messages out of order or repeated"


def test_steps_start_and_end_in_plan_order_with_their_samples_between(watched: Watched) -> None:
    expected = [s.id for s in watched.plan.steps if s.kind in ROBOT_KINDS]
    started = [m["step"] for m in of(watched, "step_start") if m["kind"] in ROBOT_KINDS]
    assert started == expected
    ended = {m["step"] for m in of(watched, "step_end")}
    assert ended == {s.id for s in watched.plan.steps}  # the report step ends when the report is written

    open_step: str | None = None
    samples_of: dict[str, int] = {}
    for m in watched.messages:
        if m["type"] == "step_start":
            assert open_step is None, f"{m['step']} started while {open_step} was running"
            open_step = m["step"]
        elif m["type"] == "samples":
            assert open_step is not None, f"samples outside any step: {m['where']}"
            assert m["step"] == open_step and m["where"].startswith(open_step)
            samples_of[open_step] = samples_of.get(open_step, 0) + len(m["points"])
        elif m["type"] == "step_end" and m["kind"] in ROBOT_KINDS:
            assert m["step"] == open_step
            open_step = None
    moving = [s.id for s in watched.plan.steps if s.kind in ("calibration_check", "trial")]
    assert set(samples_of) == set(moving)  # every motion step was seen moving, checklists were not


def test_samples_are_20_hz_inside_the_joint_range(watched: Watched) -> None:
    runs: dict[str, list[list[float]]] = {}
    for m in of(watched, "samples"):
        assert m["joint"] == "knee_flexion"
        assert np.allclose(np.diff([p[0] for p in m["points"]]), 0.05, atol=0.0015)
        if m["phase"] == "run":
            runs.setdefault(m["where"], []).extend(m["points"])
    trial = next(s for s in watched.plan.steps if s.kind == "trial")
    points = np.array(runs[trial.id])
    if watched.lost == 0:  # a pump starved by a loaded machine may shorten bursts (counted): else all there
        assert np.allclose(np.diff(points[:, 0]), 0.05, atol=0.0015)
        assert points.shape[0] >= 0.95 * trial.robot_time_s * 20
    lo, hi = 0.0, 130.0  # the knee's Eq 1 range (thesis Table 3)
    assert np.all((points[:, 1:3] > lo) & (points[:, 1:3] < hi))
    # the joint follows the command (0.2 s first-order lag): the measured angle stays near it
    assert np.median(np.abs(points[:, 1] - points[:, 2])) < 10.0


def test_progress_verdicts_and_journal_events_arrive(watched: Watched) -> None:
    last = of(watched, "progress")[-1]
    assert last["done"] == len(of(watched, "step_end"))
    assert last["robot_s_remaining"] == 0.0
    verdicts = of(watched, "verdict")
    assert [v["when"] for v in verdicts] == ["before", "after"]
    assert all(v["verdict"] == "pass" and v["settle_error_deg"] < 1.0 for v in verdicts)
    kinds = [m["kind"] for m in of(watched, "event")]
    assert kinds[0] == "started" and kinds[-1] == "finished"
    first_checklist = next(m for m in of(watched, "step_start") if m["kind"] == "calibration_check")
    assert first_checklist["next_action"]["step"].startswith("check:")


def test_status_json_describes_the_session(watched: Watched) -> None:
    s = watched.status
    assert s["session"]["protocol"] == "knee_phase1"
    assert s["session"]["mode"] == "dry-run"
    assert s["session"]["folder"] == str(watched.session)
    assert s["step"]["step"] == of(watched, "step_start")[-1]["step"]
    assert s["progress"]["done"] == of(watched, "progress")[-1]["done"]
    assert [v["step"] for v in s["verdicts"]] == [v["step"] for v in of(watched, "verdict")]
    assert s["ended"] is None  # the runner returned; the end is published when the monitor closes
    assert s["clients"] == 1
    assert s["monitor"]["max_connections"] == 16


def test_watching_changes_nothing_recorded(watched: Watched, reference_archive: Path) -> None:
    assert_same_data(reference_archive, watched.session / "archive.h5")


def test_resume_is_watched_too(watched: Watched) -> None:
    def action(live: Monitor) -> int:
        return resume(watched.session, yes=True, force=False, realtime=False, quiet=True, monitor=live)

    # a complete session is left untouched by --resume; one whose report is missing is resumed to write it
    (watched.session / "report.html").unlink()

    code, _, messages, after, _ = _watch(watched.session, action)
    assert code == 0
    session = next(m for m in messages if m["type"] == "session")
    assert session["resumed"] is True
    assert "resumed" in [m["kind"] for m in messages if m["type"] == "event"]
    started = [m["step"] for m in messages if m["type"] == "step_start"]
    assert started in ([], ["report"])  # every recorded step was already done
    assert messages[-1]["type"] == "session_end" and messages[-1]["status"] == "complete"
    assert after["progress"]["done"] == after["progress"]["total"]  # the report step too
    assert (watched.session / "report.html").is_file()
