"""What the program writes outside a session touches nothing else (archive/outputs.py, docs/report.md
"Outputs"): a report, a comparison, the CSV tables, the .mat files and a reprocessed archive never replace
a symbolic link, a device, a FIFO or a socket (exit 2 naming the path), never leave a temporary file
(a full disk, SIGTERM), get the umask's permissions, and a CSV text cell never reaches a spreadsheet as a
formula."""

from __future__ import annotations

import csv
import errno
import json
import os
import shutil
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import h5py
import pytest

from protocol_runner.archive.outputs import terminated_as_interrupt
from protocol_runner.archive.reprocess import new_archive_path, reprocess_archive
from protocol_runner.cli import main
from protocol_runner.errors import InvalidInput
from protocol_runner.report import tidy
from protocol_runner.report.tidy import export_tables, text_cell


def _fifo(path: Path) -> Path:
    os.mkfifo(path)
    return path


def _device(path: Path) -> Path:
    """A character device node like /dev/null (1, 3), made under the test's own directory."""
    try:
        os.mknod(path, stat.S_IFCHR | 0o666, os.makedev(1, 3))
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


def _link(path: Path) -> Path:
    target = path.with_name("target.txt")
    target.write_text("not ours to replace\n")
    path.symlink_to(target)
    return path


MAKERS = {"fifo": _fifo, "device": _device, "symlink": _link}


def _unchanged(path: Path, kind: str) -> bool:
    mode = os.lstat(path).st_mode
    if kind == "symlink":
        return stat.S_ISLNK(mode) and path.with_name("target.txt").read_text() == "not ours to replace\n"
    return stat.S_ISFIFO(mode) if kind == "fifo" else stat.S_ISCHR(mode)


@pytest.mark.parametrize("kind", sorted(MAKERS))
def test_report_and_comparison_never_replace_a_special_file(
    kind: str, small_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    target = MAKERS[kind](tmp_path / "report.html")
    for args in (
        ["--report", str(small_archive), "--output", str(target)],
        ["--compare", str(small_archive), str(small_archive), "--output", str(target)],
    ):
        assert main(args) == 2, args
        err = capsys.readouterr().err
        assert str(target) in err and "not a regular file" in err and "Traceback" not in err
        assert _unchanged(target, kind)
    assert [p.name for p in tmp_path.iterdir() if "partial" in p.name] == []


@pytest.mark.parametrize("kind", sorted(MAKERS))
def test_export_never_replaces_a_special_file(
    kind: str, small_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    tables = tmp_path / "tables"
    tables.mkdir()
    target = MAKERS[kind](tables / "trials.csv")
    assert main(["--export", str(small_archive), "--output", str(tables)]) == 2
    err = capsys.readouterr().err
    assert str(target) in err and "not a regular file" in err
    assert _unchanged(target, kind)
    assert not (tables / "cycles.csv").exists()  # refused before any table is written


@pytest.mark.parametrize("kind", sorted(MAKERS))
def test_export_mat_never_replaces_a_special_file(
    kind: str, reference_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "mat"
    out.mkdir()
    target = MAKERS[kind](out / "session.mat")
    assert (
        main(
            [
                "--report",
                str(reference_archive),
                "--export-mat",
                str(out),
                "--output",
                str(tmp_path / "r.html"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert str(target) in err and "not a regular file" in err
    assert _unchanged(target, kind)


def test_reprocess_never_replaces_a_link_and_skips_a_dangling_one(
    reference_archive: Path, tmp_path: Path
) -> None:
    archive = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    link = _link(tmp_path / "elsewhere.h5")
    with pytest.raises(InvalidInput, match=f"{link} is a symbolic link"):
        reprocess_archive(archive, output=link)
    (tmp_path / "archive.reprocessed.h5").symlink_to(tmp_path / "nowhere.h5")  # dangling
    assert new_archive_path(archive) == tmp_path / "archive.reprocessed-2.h5"


def test_a_reprocessed_archive_gets_the_umask_permissions(reference_archive: Path, tmp_path: Path) -> None:
    archive = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    old = os.umask(0o022)
    try:
        out = reprocess_archive(archive)
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o644
    assert [p.name for p in tmp_path.iterdir() if "partial" in p.name] == []


def test_sigterm_during_reprocess_leaves_no_copy_behind(reference_archive: Path, tmp_path: Path) -> None:
    archive = tmp_path / "archive.h5"
    shutil.copyfile(reference_archive, archive)
    proc = subprocess.Popen(
        [sys.executable, "-m", "protocol_runner.cli", "--report", str(archive), "--reprocess"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    while not any("partial" in p.name for p in tmp_path.iterdir()):
        assert proc.poll() is None and time.monotonic() < deadline, "the copy was never started"
        time.sleep(0.005)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["archive.h5"]


class _SignalledWhileFinalised:
    """Sends this process SIGTERM from its finaliser and is still inside it when the handler runs."""

    def __del__(self) -> None:
        os.kill(os.getpid(), signal.SIGTERM)
        for _ in range(10_000):  # the handler's KeyboardInterrupt is raised here, where Python drops it
            pass


@pytest.mark.skipif(os.name == "nt", reason="POSIX signals")
def test_a_sigterm_that_lands_in_a_finaliser_still_interrupts_the_block() -> None:
    with pytest.raises(KeyboardInterrupt), terminated_as_interrupt():
        finalised = _SignalledWhileFinalised()
        del finalised
        deadline = time.monotonic() + 5.0
        while time.monotonic() < deadline:  # without the redelivery the block runs on to its end
            time.sleep(0.001)


def test_a_full_disk_during_export_leaves_no_partial_file(
    small_archive: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    written = 0

    def cell(value: object) -> str:
        nonlocal written
        written += 1
        if written > 50:
            raise OSError(errno.ENOSPC, "No space left on device")
        return str(value)

    monkeypatch.setattr(tidy, "_cell", cell)
    tables = tmp_path / "tables"
    assert main(["--export", str(small_archive), "--output", str(tables)]) == 130
    assert "disk full while writing" in capsys.readouterr().err
    assert [p.name for p in tables.iterdir() if "partial" in p.name] == []


def test_csv_text_cells_never_start_a_formula_and_numbers_stay_numbers(
    small_archive: Path, tmp_path: Path
) -> None:
    archive = tmp_path / "archive.h5"
    shutil.copyfile(small_archive, archive)
    with h5py.File(archive, "r+") as f:
        cfg = next(iter(f["configurations"].values()))
        settings = json.loads(cfg.attrs["settings_json"])
        settings["friction"]["level"] = '=HYPERLINK("http://example.invalid","click")'
        settings["friction"]["friction_nm"] = -1.5
        cfg.attrs["settings_json"] = json.dumps(settings)
        key = str(cfg.attrs["key"])
    export_tables(archive, tmp_path / "tables")
    with (tmp_path / "tables" / "configurations.csv").open(newline="", encoding="utf-8") as fh:
        rows = {row["configuration"]: row for row in csv.DictReader(fh)}
    row = rows[key]
    assert row["friction"] == "'" + settings["friction"]["level"]
    assert row["friction.friction_nm"] == "-1.5"
    for cells in rows.values():
        assert not any(c.startswith(("=", "+", "@", "\t", "\r")) for c in cells.values())


@pytest.mark.parametrize(
    ("text", "shown"),
    [
        ("=1+2", "'=1+2"),
        ("+cmd", "'+cmd"),
        ("-cmd|' /C calc'!A0", "'-cmd|' /C calc'!A0"),
        ("@SUM(A1)", "'@SUM(A1)"),
        ("\tx", "'\tx"),
        ("\rx", "'\rx"),
        ("-1.5", "-1.5"),
        ("+2", "+2"),
        ("large", "large"),
    ],
)
def test_text_cells_are_neutralised_the_owasp_way(text: str, shown: str) -> None:
    assert text_cell(text) == shown


def test_a_session_path_that_is_not_utf8_still_gets_its_report(
    small_archive: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = Path(os.fsdecode(os.fsencode(tmp_path) + b"/knee-\xff-session"))
    folder.mkdir()
    shutil.copyfile(small_archive, folder / "archive.h5")
    assert main(["--report", str(folder)]) == 0, capsys.readouterr().err
    page = (folder / "report.html").read_bytes().decode("utf-8")  # valid UTF-8
    assert "knee-\ufffd-session" in page
