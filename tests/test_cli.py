"""The command line: modes, exit statuses and plain messages."""

from __future__ import annotations

import json
import os
import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from protocol_runner.cli import RUN, build_parser, check_flags, main, parse_only
from protocol_runner.errors import InvalidInput
from protocol_runner.protocol.loader import find_protocol


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "protocol_runner.cli", *args],
        cwd=cwd,
        capture_output=True,
        text=True,
        env=dict(os.environ),
    )


def test_plan_json_from_an_empty_directory_uses_the_packaged_protocol(tmp_path: Path) -> None:
    done = run_cli("--plan", "knee_phase1.yaml", "--json", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    plan = json.loads(done.stdout)
    assert plan["protocol"] == "knee_phase1"
    assert sum(1 for s in plan["steps"] if s["kind"] == "trial") == 136
    assert not any(tmp_path.iterdir())  # planning writes nothing


def test_help_explains_every_mode_with_an_example(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for mode in (
        "--dry-run",
        "--resume",
        "--report",
        "--plan",
        "--validate",
        "--hardware-check",
        "--only",
        "examples:",
    ):
        assert mode in out


def help_examples() -> list[list[str]]:
    """The commands of the examples section of --help, as argument lists (without `run-protocol` and a
    shell redirection)."""
    epilog = build_parser().epilog or ""
    section = epilog.split("examples:\n", 1)[1].split("\n\n", 1)[0]
    commands = [re.split(r"\s{2,}", line.strip())[0] for line in section.splitlines()]
    assert all(c.startswith("run-protocol ") for c in commands)
    return [shlex.split(c)[1:] for c in commands]


def test_every_help_example_works_as_written(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """No example touches the rig (a run is always --dry-run), every protocol it names is found, every
    session it reads was made by an earlier example, and each passes the flag checks; the quick ones run."""
    monkeypatch.chdir(tmp_path)
    sessions: set[str] = set()
    for argv in help_examples():
        argv = argv[: argv.index(">")] if ">" in argv else argv
        args = build_parser().parse_args(argv)
        mode = check_flags(args)
        if mode == RUN:
            assert args.dry_run, f"`run-protocol {' '.join(argv)}` would drive the rig"
        for name in (args.protocol, args.plan, args.validate):
            if name:
                assert find_protocol(name).is_file()
        if args.session:
            sessions.add(args.session)
        for read in (args.resume, args.report, args.power):
            if read:
                assert any(read == s or read.startswith(f"{s}/") for s in sessions), read
        if mode in ("--validate", "--plan") and not args.power:  # the sessions are not made here
            assert main(argv) == 0


def test_running_without_boards_exits_3_with_a_plain_message(tmp_path: Path) -> None:
    # ankle_phase2 records with USB-1608FS-Plus boards (knee_phase1's DT9814 is refused before looking)
    done = run_cli("ankle_phase2.yaml", "--session", str(tmp_path / "s"), cwd=tmp_path)
    assert done.returncode == 3
    assert "--dry-run" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "s").exists()  # nothing is created before the boards are found


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (["--report", "{tmp}/garbage.h5"], "not an HDF5 file"),
        (["--resume", "{tmp}/nowhere"], "no such session directory"),
        (["knee_phase1.yaml", "--dry-run", "--only", "99"], "no configuration has key 99"),
        (["knee_phase1.yaml", "--dry-run", "--only", "x"], "not a configuration key"),
        (["no_such_protocol.yaml", "--dry-run"], "protocol file not found"),
        (["knee_phase1.yaml", "--realtime"], "--realtime paces the simulator"),
    ],
)
def test_bad_input_exits_2_without_traceback(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], needle: str
) -> None:
    (tmp_path / "garbage.h5").write_bytes(b"not hdf5 at all" * 10)
    argv = [a.replace("{tmp}", str(tmp_path)) for a in args]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err


def test_second_session_in_the_same_directory_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    session = tmp_path / "s"
    session.mkdir()
    (session / "session.json").write_text("{}")
    assert main(["knee_phase1.yaml", "--dry-run", "--only", "12", "--session", str(session)]) == 2
    assert "--resume" in capsys.readouterr().err


def test_parse_only_accepts_lists_and_ranges() -> None:
    keys = range(1, 34)
    assert parse_only("4,5,6,7").select(keys, "p.yaml") == [4, 5, 6, 7]  # type: ignore[union-attr]
    assert parse_only("12-14,27").select(keys, "p.yaml") == [12, 13, 14, 27]  # type: ignore[union-attr]
    assert parse_only(None) is None
    with pytest.raises(InvalidInput):
        parse_only("14-12")


def test_seed_out_of_range_is_refused_before_running(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert (
        main(["knee_phase1.yaml", "--dry-run", "--seed", str(2**70), "--session", str(tmp_path / "s")]) == 2
    )
    assert "--seed" in capsys.readouterr().err and not (tmp_path / "s").exists()


def test_session_that_is_a_file_is_refused(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    (tmp_path / "afile").write_text("x")
    assert main(["knee_phase1.yaml", "--dry-run", "--only", "12", "--session", str(tmp_path / "afile")]) == 2
    assert "is a file" in capsys.readouterr().err


def test_the_protocol_may_come_before_plan_or_validate(capsys: pytest.CaptureFixture[str]) -> None:
    """`run-protocol X.yaml --plan --json` is the same request as `run-protocol --plan X.yaml --json`."""
    assert main(["--plan", "knee_phase1.yaml", "--json"]) == 0
    flag_first = capsys.readouterr().out
    assert main(["knee_phase1.yaml", "--plan", "--json"]) == 0
    protocol_first = capsys.readouterr().out
    assert protocol_first == flag_first and json.loads(protocol_first)["protocol"] == "knee_phase1"
    assert main(["knee_phase1.yaml", "--validate"]) == 0
    assert "valid" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "says"),
    [
        (["--plan"], "--plan needs a PROTOCOL"),
        (["--validate"], "--validate needs a PROTOCOL"),
        (["a.yaml", "--plan", "b.yaml"], "a second protocol a.yaml"),
    ],
)
def test_plan_or_validate_with_no_protocol_or_two_is_refused(
    argv: list[str], says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err


def test_a_run_prints_its_outcome_on_stdout_and_its_progress_on_stderr(tmp_path: Path) -> None:
    session = tmp_path / "s"
    done = run_cli("knee_phase1.yaml", "--dry-run", "--only", "15", "--session", str(session), cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines() == [f"done: {session / 'archive.h5'} and {session / 'report.html'}"]
    assert "done:" not in done.stderr and "] report" in done.stderr  # the progress stays on stderr
