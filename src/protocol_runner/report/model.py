"""What the report shows: immutable data read from one archive (docs/archive.md) by
`load.load_report_data`, nothing else. Plot series are decimated (a processed trial is smooth after the
pipeline's low-pass filter, thesis §4.4); summary numbers (angle range, torque-angle slope) come from the
full-rate data. Arrays are read-only numpy arrays; units are in the field names.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from ..analysis.reference import FloatArray, ReferenceDataset
from ..protocol.plan_steps import Comparison
from .settings_view import DeviceElement, Quantity, SettingsView


class _EnergyPerCycle:
    """The energy lost per cycle (Eq 10-12) over every cycle of every trial (`energy_loss_j`)."""

    energy_loss_j: FloatArray

    @property
    def energy_mean_j(self) -> float:
        """Its mean; NaN without a cycle."""
        return float(np.mean(self.energy_loss_j)) if self.energy_loss_j.size else float("nan")

    @property
    def energy_std_j(self) -> float:
        """Its sample standard deviation (spread across cycles and trials); NaN with fewer than two cycles."""
        return float(np.std(self.energy_loss_j, ddof=1)) if self.energy_loss_j.size > 1 else float("nan")


@dataclass(frozen=True)
class SessionEvent:
    """One line of `/session/events`: an interruption, a resume, a re-run calibration, ..."""

    t_utc: str
    kind: str
    detail: str


@dataclass(frozen=True)
class ChecklistAnswer:
    """One operator checklist of `/session/checklists/<step>` and how it was answered."""

    step_id: str
    title: str
    items: tuple[str, ...]
    answer: str
    answered_utc: str
    automatic: bool


@dataclass(frozen=True)
class SessionInfo:
    """The archive's root attributes (docs/archive.md "Root") plus the session log."""

    archive_path: str
    protocol_name: str
    protocol_sha256: str
    schema_version: int
    software_version: str
    mode: str
    seed: int
    created_utc: str
    finished_utc: str
    status: str
    joint: str
    only: tuple[int, ...]
    events: tuple[SessionEvent, ...] = ()
    checklists: tuple[ChecklistAnswer, ...] = ()

    @property
    def complete(self) -> bool:
        """True when the session ran to its end (root `status` is "complete")."""
        return self.status == "complete"

    @property
    def joints(self) -> tuple[str, ...]:
        """The driven joints, in channel order (the root attribute `joint`, comma-separated)."""
        return tuple(j.strip() for j in self.joint.split(",") if j.strip())

    @property
    def interruptions(self) -> tuple[SessionEvent, ...]:
        """The interruption and resume events, in the order they happened."""
        return tuple(e for e in self.events if e.kind in ("interrupted", "resumed"))


@dataclass(frozen=True)
class CalibrationCheck:
    """One joint's calibration step response (`/calibration/<set>/<when>`, or its `joints/<joint>` with
    several joints; Appendix A "Calibration": a 45° step)."""

    set_name: str
    when: str
    joint: str
    step_id: str
    verdict: str
    step_deg: float
    settle_error_deg: float
    time_constant_s: float
    limits: str
    message: str
    time_s: FloatArray
    angle_deg: FloatArray
    command_time_s: FloatArray
    command_deg: FloatArray


@dataclass(frozen=True)
class Recording:
    """One brace-on or brace-off acquisition, decimated for plotting (angle and torque vs time)."""

    time_s: FloatArray
    angle_deg: FloatArray
    torque_nm: FloatArray
    command_time_s: FloatArray
    command_deg: FloatArray
    tick_lateness_p99_s: float


@dataclass(frozen=True)
class ProcessedTrial:
    """The brace's own torque against angle after transition removal, filtering and subtraction (§3.3)."""

    angle_deg: FloatArray  # decimated for plotting (report/h5read.decimate_for_plot)
    brace_torque_nm: FloatArray
    subtraction: str
    filter_text: str = ""  # e.g. "Butterworth low-pass, order 10, cut-off 50.0 Hz, zero-phase"
    # from every stored sample, not the plotted copy (report/headline.py); NaN when not computed
    range_deg: float = math.nan  # 99th minus 1st percentile of the angle
    slope_nm_per_deg: float = math.nan  # least-squares slope of brace torque against angle
    peak_nm: float = math.nan  # largest absolute brace torque


@dataclass(frozen=True)
class BraceOffMatch:
    """How well a trial's brace-off twin matched it (docs/analysis.md §3-4): the kept scaling run's
    cycle-range error (deg), the robot runs the scaling made, whether the error is within the protocol's
    tolerance, and the clipped fraction (1 - the processed data's `coverage`); None where the archive holds
    no value (an equal-time subtraction, a twin replayed without scaling, a trial not processed)."""

    scaling_error_deg: float | None = None
    scaling_runs: int | None = None
    scaling_converged: bool | None = None
    clipped_fraction: float | None = None


@dataclass(frozen=True)
class Trial:
    """Trial `number` of a configuration: its brace-on and brace-off runs and the processed result.

    `brace_on`/`brace_off` are read only for the configuration's first recorded trial (the one plotted
    against time); `recorded`: the archive holds this trial's raw data."""

    number: int
    brace_on: Recording | None
    brace_off: Recording | None
    processed: ProcessedTrial | None
    recorded: bool = True
    match: BraceOffMatch = BraceOffMatch()


@dataclass(frozen=True)
class FittedCurve:
    """A fit's model against the data it was fitted to (its `angle_deg`, `torque_nm` and `model_torque_nm`
    datasets, docs/archive.md "Fits"), decimated for plotting; empty arrays when the archive has none."""

    angle_deg: FloatArray
    torque_nm: FloatArray
    model_torque_nm: FloatArray


@dataclass(frozen=True)
class BoucWenFit(FittedCurve):
    """The generalised Bouc-Wen fit of one configuration (thesis §6.2, Eq 19-25), its curve the centred
    data and the model's prediction."""

    A: float
    n: float
    beta: tuple[float, ...]
    rmse_nm: float
    r2: float
    cv_rmse_nm: tuple[float, ...]
    n_starts: int
    # the fit's evidence (absent from older archives: NaN / empty / False)
    rmse_refined_nm: float = float("nan")
    optimizer_status: int = 0
    cost_spread: float = float("nan")
    n_interval: tuple[float, ...] = ()
    weakly_identified: bool = False
    weak_reasons: str = ""
    model_energy_j: float = float("nan")
    data_energy_j: float = float("nan")
    model_dissipates: bool = True
    backbone: str = "none"  # "polynomial": torque = g(angle) + z
    param_interval_low: tuple[float, ...] = ()  # 95 % intervals of A, n, β1-β6
    param_interval_high: tuple[float, ...] = ()
    # from the model comparison (`fits/models`), when it ran: which of A, n, β1-β6 the data identify, and
    # what the loops determine: (name, unit, value, 95 % low, 95 % high) per functional
    parameter_identified: tuple[bool, ...] = ()
    functionals: tuple[tuple[str, str, float, float, float], ...] = ()


@dataclass(frozen=True)
class ElementFit(FittedCurve):
    """The device's elastic elements fitted to the loops' midline (`fits/elements`, docs/archive.md):
    `parameters` by archive name `<element>.<parameter>` (the unit in its suffix), `elements` with every
    parameter; the curve is the midline data (`torque_nm`) and the model against `angle_deg`."""

    applicable: bool
    reason: str
    target: str
    rmse_nm: float
    rmse_all_samples_nm: float
    parameters: tuple[tuple[str, float], ...]
    elements: tuple[DeviceElement, ...]

    @property
    def drawable(self) -> bool:
        """True when the fit applies and has a model curve to draw (angles and the model's torques)."""
        return self.applicable and self.angle_deg.size > 0 and self.model_torque_nm.size > 0


@dataclass(frozen=True)
class Configuration(_EnergyPerCycle):
    """One joint's part of one row of the test matrix (Appendix A, Table 5): the row's identity and
    settings, and that joint's trials and results. A configuration driving several joints is one
    `Configuration` per joint, each with the same key."""

    name: str
    key: int
    joint: str
    run: int
    set_name: str
    condition: str
    profile: str
    status: str
    n_trials_planned: int
    settings: SettingsView
    trials: tuple[Trial, ...]
    energy_loss_j: FloatArray
    energy_cycle_trial: FloatArray
    bouc_wen: BoucWenFit | None
    element_fit: ElementFit | None
    angle_min_deg: float
    angle_max_deg: float
    trajectory_json: str = ""  # the plan's JSON of the first recorded brace-on trial's trajectory

    @property
    def has_data(self) -> bool:
        """True when at least one trial was processed."""
        return any(t.processed is not None for t in self.trials)

    def level(self, factor: str) -> str | None:
        """The level label of declared factor `factor`, or None when this configuration does not set it."""
        return self.settings.level(factor)

    def quantity(self, factor: str, name: str) -> Quantity | None:
        """The value of `factor`'s quantity `name` (a number, or a tuple for a list), or None."""
        return self.settings.quantity(factor, name)


def factor_names(configurations: Sequence[Configuration]) -> list[str]:
    """Every declared factor any of `configurations` sets, in declaration order (first seen first)."""
    names: list[str] = []
    for cfg in configurations:
        names.extend(f for f in cfg.settings.factor_names() if f not in names)
    return names


@dataclass(frozen=True)
class JointsTotal(_EnergyPerCycle):
    """The energy lost per cycle by all the driven joints of a configuration together (its
    `total_energy_loss_j` and `total_energy_cycle_trial`, docs/archive.md "Several joints": for each trial,
    the sum over the joints of their k-th complete cycle's energy)."""

    key: int
    energy_loss_j: FloatArray
    energy_cycle_trial: FloatArray


@dataclass(frozen=True)
class ReportData:
    """Everything the report shows, read from one archive: one `Configuration` per configuration and driven
    joint, in key order and, within a key, in the joints' channel order (`joints`); `totals`, the energy of
    all joints together of each configuration driving several joints (none for a single joint)."""

    session: SessionInfo
    configurations: tuple[Configuration, ...]
    calibration: tuple[CalibrationCheck, ...]
    comparisons: tuple[Comparison, ...]
    references: tuple[ReferenceDataset, ...] = ()
    protocol_text: str = ""
    notes: tuple[str, ...] = field(default=())
    joints: tuple[str, ...] = ()
    totals: tuple[JointsTotal, ...] = ()

    @property
    def multi_joint(self) -> bool:
        """True when the archive drives several joints (its figures and tables are then per joint)."""
        return len(self.joints) > 1

    @property
    def keys(self) -> tuple[int, ...]:
        """The configuration keys, in order, each once."""
        return tuple(dict.fromkeys(cfg.key for cfg in self.configurations))

    def configuration(self, key: int, joint: str | None = None) -> Configuration | None:
        """The part of configuration `key` of joint `joint` (None: of its first driven joint, the only one
        of a single-joint archive), or None if the archive has none."""
        return next(
            (cfg for cfg in self.configurations if cfg.key == key and joint in (None, cfg.joint)), None
        )

    def joint_configurations(self, key: int) -> tuple[Configuration, ...]:
        """Every joint's part of configuration `key`, in channel order (empty if the archive has none)."""
        return tuple(cfg for cfg in self.configurations if cfg.key == key)

    def total(self, key: int) -> JointsTotal | None:
        """The energy of all joints together of configuration `key`, or None (a single joint, or none)."""
        return next((t for t in self.totals if t.key == key), None)
