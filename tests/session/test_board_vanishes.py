"""A board that vanishes mid-trial: the trial is kept as failed with its data so far, the joint is parked
(if the output board still answers), the session stops with exit 3 and resumes to the same data."""

from __future__ import annotations

from pathlib import Path

import h5py
import pytest

from protocol_runner.commands import resume
from protocol_runner.hardware.usb_common import DeviceGone
from protocol_runner.protocol.loader import find_protocol, load_protocol
from protocol_runner.session.journal import Journal
from protocol_runner.session.operator import AutoOperator
from protocol_runner.session.rigs import SimulatedBench
from protocol_runner.session.runner import Runner
from protocol_runner.session.setup import create_session, load_session_protocol

from .conftest import ONLY, SEED, assert_same_data


class VanishingInput:
    """Wraps the simulated input board; after `rows` samples it is unplugged (errno 19, like pyusb)."""

    def __init__(self, inner: object, rows: int) -> None:
        self.inner = inner
        self.rows_left = rows
        self.armed = False

    def __getattr__(self, name: str) -> object:
        return getattr(self.inner, name)

    def read_available(self):  # type: ignore[no-untyped-def]
        block = self.inner.read_available()  # type: ignore[attr-defined]
        if self.armed:
            self.rows_left -= block.n_samples
            if self.rows_left <= 0:
                raise DeviceGone("USB input board vanished (No such device, errno 19); check its cable")
        return block


def test_board_vanishing_mid_trial_keeps_data_stops_with_3_and_resumes(
    tmp_path: Path, reference_archive: Path
) -> None:
    loaded = load_protocol(find_protocol("knee_phase1.yaml"))
    session = tmp_path / "vanish"
    info = create_session(session, loaded, mode="dry-run", seed=SEED, only=tuple(ONLY), realtime=False)
    stored, plan, _ = load_session_protocol(session, info, force=False)
    bench = SimulatedBench(stored, seed=SEED)
    flaky = VanishingInput(bench.rig.ai, rows=10_000)  # 10 s into the trial
    bench.rig.ai = flaky  # type: ignore[assignment]
    original_begin = bench.begin_step

    def begin(step_id: str) -> None:
        original_begin(step_id)
        flaky.armed = step_id == "trial:k12:on:2"

    bench.begin_step = begin  # type: ignore[method-assign]
    runner = Runner(session, info, stored, plan, bench, AutoOperator(), quiet=True)
    with pytest.raises(DeviceGone) as info_exc:
        runner.run()
    assert info_exc.value.exit_code == 3 and "--resume" in info_exc.value.message
    journal = Journal(session / "journal.jsonl")
    assert "trial:k12:on:1" in journal.units
    assert "trial:k12:on:2" not in journal.units and "trial:k12:on:2" in journal.failed
    with h5py.File(session / "archive.h5", "r") as f:
        assert f.attrs["status"] == "incomplete"
        failed = f["configurations/config_12/trials/2/brace_on"]
        assert failed.attrs["status"] == "failed"
        # the data up to the failure are kept (the 10,000 rows include the approach move before the trial)
        assert 8_000 <= failed["time_s"].shape[0] <= 10_000
        kinds = [e for e in f["session/events"].asstr()[:] if '"stopped"' in e]
        assert kinds and "vanished" in kinds[0]
    # the board is back: resume redoes the failed trial and the session ends as if nothing happened
    assert resume(session, yes=True, force=False, realtime=False, quiet=True) == 0
    assert_same_data(reference_archive, session / "archive.h5")
