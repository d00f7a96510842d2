"""The report's headline numbers per configuration, on trials as the experimental unit.

One `ConfigurationStats` per configuration and joint (and, with several joints, one of all joints
together, from `total_energy_loss_j`): trials and cycles analysed, energy per cycle as the mean of
trial means with its 95 % t-interval and between-trial CV (`analysis.statistics`), the angle range
reached, and the Bouc-Wen fit quality. The report's summary table, the tidy CSV exports and the session
comparison all read these, so they print the same intervals.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from protocol_runner.analysis.statistics import (
    TInterval,
    t_interval,
    trial_means,
)
from protocol_runner.report.model import Configuration, JointsTotal, ReportData

ALL_JOINTS = "all joints"


@dataclass(frozen=True)
class ConfigurationStats:
    """Trial-level summary of one configuration: the trials with at least one complete cycle with a finite
    energy (`trial_numbers`, in trial order) and their energy per cycle (`trial_energy_j`: the mean over the
    trial's complete cycles with a finite energy, Eq 10-12), the units of the interval and of repeatability."""

    key: int
    set_name: str
    cycles: int
    trial_numbers: tuple[int, ...]
    trial_energy_j: tuple[float, ...]
    energy: TInterval
    angle_min_deg: float
    angle_max_deg: float
    fit_rmse_nm: float
    fit_r2: float
    joint: str = ""  # the joint, or ALL_JOINTS for the energy of all joints together

    @property
    def trials(self) -> int:
        """Trials with at least one complete cycle."""
        return len(self.trial_numbers)


def configuration_stats(cfg: Configuration, total: JointsTotal | None = None) -> ConfigurationStats:
    """The trial-level statistics of `cfg` (energy per cycle grouped by `energy_cycle_trial`); with `total`,
    of the energy of all joints of `cfg`'s configuration together: no angle range or fit (those are each
    joint's)."""
    energy = np.asarray((cfg if total is None else total).energy_loss_j, dtype=float)
    ids = np.asarray((cfg if total is None else total).energy_cycle_trial)
    if ids.size != energy.size:
        ids = np.zeros(energy.size, dtype=np.int64)
    numbers, means = trial_means(energy, ids)
    fit = cfg.bouc_wen if total is None else None
    return ConfigurationStats(
        key=cfg.key,
        set_name=cfg.set_name,
        cycles=int(np.sum(np.isfinite(energy))),
        trial_numbers=tuple(int(n) for n in numbers),
        trial_energy_j=tuple(float(m) for m in means),
        energy=t_interval(means),
        angle_min_deg=cfg.angle_min_deg if total is None else math.nan,
        angle_max_deg=cfg.angle_max_deg if total is None else math.nan,
        fit_rmse_nm=fit.rmse_nm if fit is not None else math.nan,
        fit_r2=fit.r2 if fit is not None else math.nan,
        joint=cfg.joint if total is None else ALL_JOINTS,
    )


def headline_stats(data: ReportData, key: int) -> tuple[ConfigurationStats, ...]:
    """The statistics of configuration `key`: each joint's, and with several joints all joints' together
    last (when the archive holds that total)."""
    cfgs = data.joint_configurations(key)
    total = data.total(key)
    rows = [configuration_stats(cfg) for cfg in cfgs]
    if data.multi_joint and total is not None and cfgs:
        rows.append(configuration_stats(cfgs[0], total))
    return tuple(rows)


def campaign_stats(data: ReportData, key: int) -> ConfigurationStats | None:
    """The statistics a campaign-level number of configuration `key` uses: its one joint's, or with
    several joints all joints' together (None when there is no such total)."""
    rows = headline_stats(data, key)
    if not rows or (data.multi_joint and rows[-1].joint != ALL_JOINTS):
        return None
    return rows[-1] if data.multi_joint else rows[0]
