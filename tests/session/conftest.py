"""Helpers for the session tests: dry runs in-process and in a subprocess, archive comparison."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import h5py
import numpy as np

from protocol_runner.commands import run

ONLY = [12]  # one short configuration (R1/Rr1, 25 s trials): quick but every step kind runs
SEED = 7

# Attributes and datasets that legitimately differ between two runs: wall-clock times and event logs.
# (`attribute_sha256` holds the checksums of the wall-clock values too)
VOLATILE_ATTRS = {"created_utc", "finished_utc", "answered_utc", "attribute_sha256"}
VOLATILE_PATHS = ("session/events",)


def run_dry(
    session: Path, *, only: list[int] | None = None, seed: int = SEED, protocol: str = "knee_phase1.yaml"
) -> int:
    return run(
        protocol,
        dry_run=True,
        session=session,
        seed=seed,
        yes=True,
        only=ONLY if only is None else only,
        realtime=False,
        quiet=True,
    )


class Cli:
    """`run-protocol ...` in a subprocess; its stderr goes to a file (a pipe could fill up and block it)."""

    def __init__(self, *args: str, log: Path) -> None:
        env = dict(os.environ)
        env["PYTHONUNBUFFERED"] = "1"
        self.log = log
        with log.open("ab") as err:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "protocol_runner.cli", *args],
                stdout=subprocess.DEVNULL,
                stderr=err,
                env=env,
            )

    def poll(self) -> int | None:
        return self.proc.poll()

    def send_signal(self, sig: int) -> None:
        self.proc.send_signal(sig)

    def wait(self, timeout: float | None = None) -> int:
        return self.proc.wait(timeout=timeout)

    @property
    def returncode(self) -> int | None:
        return self.proc.returncode

    def stderr(self) -> str:
        return self.log.read_text(errors="replace")


def cli(*args: str, log: Path) -> Cli:
    return Cli(*args, log=log)


def archive_contents(path: Path) -> dict[str, object]:
    """Every dataset (as bytes) and every attribute of an archive, minus wall-clock values."""
    out: dict[str, object] = {}
    with h5py.File(path, "r") as f:

        def visit(name: str, obj: h5py.HLObject) -> None:
            if name.startswith(VOLATILE_PATHS):
                return
            if isinstance(obj, h5py.Dataset):
                value = obj[()]
                out[name] = value.tobytes() if isinstance(value, np.ndarray) else value
            for key, value in obj.attrs.items():
                if key in VOLATILE_ATTRS:
                    continue
                out[f"{name}@{key}"] = _comparable(value)

        f.visititems(visit)
        for key, value in f.attrs.items():
            if key not in VOLATILE_ATTRS:
                out[f"/@{key}"] = value.tobytes() if isinstance(value, np.ndarray) else value
    return out


def _comparable(value: object) -> object:
    """Numeric arrays by their bytes; string arrays (object dtype: pointers) by their values."""
    if isinstance(value, np.ndarray):
        return value.tolist() if value.dtype == object else value.tobytes()
    return value


def assert_same_data(reference: Path, other: Path) -> None:
    ref = archive_contents(reference)
    got = archive_contents(other)
    missing = sorted(set(ref) - set(got))
    assert not missing, f"missing in the resumed archive: {missing[:10]}"
    different = sorted(k for k in ref if ref[k] != got[k])
    assert not different, f"differ from the uninterrupted run: {different[:10]}"


def copy_session(reference_archive: Path, to: Path) -> Path:
    """A copy of the reference session (its lock aside) at `to`."""
    shutil.copytree(reference_archive.parent, to, ignore=shutil.ignore_patterns(".lock", ".lock.pid"))
    return to
