"""analysis/service.py: one configuration's whole analysis in one pure function, the one path of the
session's processing and fit steps and of --reprocess."""

from __future__ import annotations

from pathlib import Path

import h5py
import numpy as np
import pytest

from protocol_runner.analysis.centring import complete_cycles_span
from protocol_runner.analysis.pipeline import Recording, TrialPair, process_configuration
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.analysis.service import (
    PROCESSED_RATE_HZ,
    BoucWenSettings,
    analyse_configuration,
    analyse_joints,
    fit_stored_loops,
)
from protocol_runner.archive.results import processed_fill, read_processed_loops

from .synth import RawTrial, raw_trial

QUICK = BoucWenSettings(starts=1, cross_validate=False, backbone="none")


def _recording(r: RawTrial) -> Recording:
    return Recording(r.time_s, r.angle_deg, r.torque_nm, r.command_deg, r.command_time_s)


def _pairs(*seeds: int) -> list[TrialPair]:
    """One trial pair per seed, numbered 1, 2, ..."""
    return [
        TrialPair(
            _recording(raw_trial(brace=True, seed=n)), _recording(raw_trial(brace=False, seed=100 + n)), i
        )
        for i, n in enumerate(seeds, start=1)
    ]


@pytest.fixture(scope="module")
def pairs() -> list[TrialPair]:
    return _pairs(1, 2)


def test_the_stored_loops_are_the_processed_ones_at_200_hz_in_float32(pairs: list[TrialPair]) -> None:
    analysis = analyse_configuration(pairs, ProcessingSettings())
    assert analysis.bouc_wen is None  # no fit asked
    for t, s in zip(analysis.processed.trials, analysis.stored, strict=True):
        assert s.trial == t.trial and s.decimation == 5  # 1 kHz input -> 200 Hz
        assert s.input_rate_hz == pytest.approx(1000.0) and s.sample_rate_hz == pytest.approx(
            PROCESSED_RATE_HZ
        )
        assert s.angle_deg.dtype == np.float32 and s.brace_torque_nm.dtype == np.float32
        np.testing.assert_array_equal(s.angle_deg, t.angle_deg[::5].astype(np.float32))
        np.testing.assert_array_equal(s.brace_torque_nm, t.brace_torque_nm[::5].astype(np.float32))
        np.testing.assert_array_equal(s.time_s, t.time_s[::5])


def test_processing_is_the_pipeline_s(pairs: list[TrialPair]) -> None:
    direct = process_configuration(pairs, ProcessingSettings())
    served = analyse_configuration(pairs, ProcessingSettings()).processed
    np.testing.assert_array_equal(served.energy_loss_j, direct.energy_loss_j)
    np.testing.assert_array_equal(served.energy_cycle_trial, direct.energy_cycle_trial)


def test_the_fit_of_the_archived_loops_is_the_fit_of_the_whole_analysis(
    pairs: list[TrialPair], tmp_path: Path
) -> None:
    """The session fits what its process step stored and read back from the unit; --reprocess fits in one
    call: both give the same numbers, bit for bit."""
    settings = ProcessingSettings()
    whole = analyse_configuration(pairs, settings, QUICK)
    with h5py.File(tmp_path / "unit.h5", "w") as f:
        processed_fill("config_01", analyse_configuration(pairs, settings), settings)(f)
        loops = read_processed_loops(f["configurations/config_01/trials"])
    apart = fit_stored_loops(loops, QUICK)
    assert whole.bouc_wen is not None
    assert apart.fit.params == whole.bouc_wen.fit.params
    assert apart.fit.rmse_nm == whole.bouc_wen.fit.rmse_nm
    for a, b in zip(apart.model_torque_nm, whole.bouc_wen.model_torque_nm, strict=True):
        np.testing.assert_array_equal(a, b)
    # the fit ran on the stored (decimated) loops, centred: ~1/5 of the processed samples per trial
    n_stored = [len(s.angle_deg) for s in whole.stored]
    assert [len(x) for x, _ in whole.bouc_wen.segments] == n_stored
    assert all(abs(float(np.mean(x[complete_cycles_span(x)]))) < 1e-3 for x, _ in whole.bouc_wen.segments)


def test_several_joints_are_analysed_joint_by_joint_with_their_total_per_cycle(
    pairs: list[TrialPair],
) -> None:
    other = _pairs(3, 4)
    settings = ProcessingSettings()
    legs = analyse_joints(
        [("hip", pairs), ("knee", other)],
        settings,
        QUICK,
        devices={"hip": None, "knee": None},
        fitted_joints=["knee"],
    )
    hip, knee = legs.analyses
    assert legs.joints == ("hip", "knee")
    assert hip.bouc_wen is None and knee.bouc_wen is not None  # only the joints asked are fitted
    np.testing.assert_array_equal(
        hip.processed.energy_loss_j, process_configuration(pairs, settings).energy_loss_j
    )
    for n in (1, 2):
        e_hip = hip.processed.energy_loss_j[hip.processed.energy_cycle_trial == n]
        e_knee = knee.processed.energy_loss_j[knee.processed.energy_cycle_trial == n]
        k = min(e_hip.size, e_knee.size)
        assert k > 0
        np.testing.assert_array_equal(
            legs.total_energy_loss_j[legs.total_energy_cycle_trial == n], e_hip[:k] + e_knee[:k]
        )
