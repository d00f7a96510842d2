"""Analysis as a service (docs/analysis.md "One configuration's whole analysis"): `analyse_configuration`
runs `pipeline.process_configuration`, stores the processed loops (`stored_trial`: decimated to
`PROCESSED_RATE_HZ`, float32) and, when asked, fits the Bouc-Wen model to those stored loops
(`fit_stored_loops`). A session's fit step and `--reprocess` both fit the stored loops, so a re-processing
with unchanged settings reproduces the session's numbers bit for bit. `analyse_joints` does it per joint of
several joints moved together and sums their energy per cycle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt

from ..models.bouc_wen.records import BoucWenFit
from .bouc_wen_fit import LoopEnergy, centred_loop, fit_loops, loop_energy, model_torques
from .joint_energy import total_energy_per_cycle
from .pipeline import ConfigurationResult, ProcessedTrial, TrialPair, process_configuration
from .processing_settings import ProcessingSettings
from .validation import SIGNAL, FloatArray

Loop = tuple[np.ndarray, np.ndarray]
Backbone = Literal["polynomial", "elements", "none"]

#: The processed loops are stored at this rate (low-passed far below 100 Hz, so nothing is lost; energies
#: and the element fit are computed before this decimation, at the full input rate).
PROCESSED_RATE_HZ = 200.0


@dataclass(frozen=True)
class BoucWenSettings:
    """How the Bouc-Wen model is fitted (the protocol's `fits.bouc_wen`): `backbone` g of torque = g(angle)
    + z is a polynomial of degree `backbone_degree`, the device's elastic elements (g = 0 when the element
    fit is off) or "none" (the thesis form torque = z)."""

    starts: int = 8
    cross_validate: bool = True
    backbone: Backbone = "polynomial"
    backbone_degree: int = 9

    @property
    def polynomial_degree(self) -> int | None:
        return self.backbone_degree if self.backbone == "polynomial" else None


@dataclass(frozen=True)
class StoredTrial:
    """A processed trial as the archive stores it (`trials/<n>/processed`): decimated by `decimation` to
    about `PROCESSED_RATE_HZ`, angle and torque in `SIGNAL` precision."""

    trial: int
    time_s: FloatArray
    angle_deg: npt.NDArray[np.float32]
    brace_torque_nm: npt.NDArray[np.float32]
    input_interval_s: float  # the median sample interval the trial was processed (and filtered) at
    decimation: int

    @property
    def input_rate_hz(self) -> float:
        return 1.0 / self.input_interval_s

    @property
    def sample_rate_hz(self) -> float:
        return 1.0 / (self.input_interval_s * self.decimation)

    @property
    def loop(self) -> Loop:
        return self.angle_deg, self.brace_torque_nm


@dataclass(frozen=True)
class BoucWenResult:
    """The Bouc-Wen fit of a configuration's centred loops (`segments`), its leave-one-trial-out RMSEs
    (N*m, empty when not asked or one trial), the model's torque on every sample of each segment and the
    model's and data's mean energy per cycle (J)."""

    fit: BoucWenFit
    cv_rmse_nm: list[float]
    segments: list[Loop]
    model_torque_nm: list[np.ndarray]
    energy: LoopEnergy


@dataclass(frozen=True)
class ConfigurationAnalysis:
    """Everything the analysis gives for one configuration."""

    processed: ConfigurationResult
    stored: tuple[StoredTrial, ...]
    bouc_wen: BoucWenResult | None


@dataclass(frozen=True)
class JointsAnalysis:
    """Several joints moved together: each joint's analysis (in `joints` order) and the leg's total energy
    per cycle (J) with each total's trial number."""

    joints: tuple[str, ...]
    analyses: tuple[ConfigurationAnalysis, ...]
    total_energy_loss_j: FloatArray
    total_energy_cycle_trial: npt.NDArray[np.int64]


def stored_trial(t: ProcessedTrial) -> StoredTrial:
    """`t` decimated to about PROCESSED_RATE_HZ (its input rate from the median sample interval)."""
    dt = float(np.median(np.diff(t.time_s))) if t.time_s.size > 1 else 1.0
    stride = max(1, round(1.0 / (dt * PROCESSED_RATE_HZ)))
    return StoredTrial(
        trial=t.trial,
        time_s=np.asarray(t.time_s[::stride]),
        angle_deg=np.asarray(t.angle_deg[::stride], dtype=SIGNAL),
        brace_torque_nm=np.asarray(t.brace_torque_nm[::stride], dtype=SIGNAL),
        input_interval_s=dt,
        decimation=stride,
    )


def fit_stored_loops(
    loops: Sequence[Loop], settings: BoucWenSettings, device: Sequence[object] | None = None
) -> BoucWenResult:
    """The Bouc-Wen fit over a configuration's stored processed loops (uncentred `(angle_deg,
    brace_torque_nm)` per trial, in trial order), each centred on (0, 0) first (§6.2.3 note). `device`
    (None when the element fit is off) is the elastic-element backbone's, used with backbone "elements"."""
    raw = list(loops)
    segments = [centred_loop(a, t) for a, t in raw]
    fit, cv = fit_loops(
        segments,
        starts=settings.starts,
        cross_validated=settings.cross_validate,
        backbone_degree=settings.polynomial_degree,
        elements=(raw, device) if settings.backbone == "elements" else None,
    )
    return bouc_wen_result(fit, segments, cv)


def bouc_wen_result(fit: BoucWenFit, segments: Sequence[Loop], cv_rmse_nm: Sequence[float]) -> BoucWenResult:
    """A fit of `segments` with the model's torque on each and the model's and data's loop energy."""
    models = model_torques(segments, fit)
    return BoucWenResult(fit, list(cv_rmse_nm), list(segments), models, loop_energy(segments, models))


def analyse_configuration(
    recordings: Sequence[TrialPair],
    processing: ProcessingSettings,
    fit: BoucWenSettings | None = None,
    *,
    device: Sequence[object] | None = None,
) -> ConfigurationAnalysis:
    """Process one configuration's trial pairs, and fit the Bouc-Wen model to the stored loops when `fit`
    is given. `device`: the configuration's elastic elements for the element fit and the "elements"
    backbone, or None when the element fit is off."""
    processed = process_configuration(recordings, processing, device=device)
    stored = tuple(stored_trial(t) for t in processed.trials)
    bouc_wen = fit_stored_loops([s.loop for s in stored], fit, device) if fit is not None else None
    return ConfigurationAnalysis(processed, stored, bouc_wen)


def analyse_joints(
    recordings: Sequence[tuple[str, Sequence[TrialPair]]],
    processing: ProcessingSettings,
    fit: BoucWenSettings | None = None,
    *,
    devices: dict[str, Sequence[object] | None],
    fitted_joints: Sequence[str] = (),
) -> JointsAnalysis:
    """`analyse_configuration` per joint (`recordings`: (joint, its trial pairs) in channel order, each
    joint with `devices[joint]`; the Bouc-Wen fit only for `fitted_joints`), and the total energy per
    cycle over the joints (the k-th complete cycle of every joint summed, `total_energy_per_cycle`)."""
    joints = tuple(joint for joint, _ in recordings)
    analyses = tuple(
        analyse_configuration(
            pairs, processing, fit if joint in fitted_joints else None, device=devices.get(joint)
        )
        for joint, pairs in recordings
    )
    total, which = total_energy_per_cycle(
        [a.processed.energy_loss_j for a in analyses], [a.processed.energy_cycle_trial for a in analyses]
    )
    return JointsAnalysis(joints, analyses, total, which)
