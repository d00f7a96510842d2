"""Processing of one configuration's trials: the thesis's procedure end to end (§3.2-3.3, §4.4, §5.7, §6.1).

For each trial pair (the brace-on recording and its brace-off counterpart):

1. bring the command onto the input time base (`transition.command_on_input_base`) if it has its own;
2. cut the start-up transition of each recording (§3.3.1, `transition.remove_transition`);
3. low-pass filter angle and torque, zero phase (§3.2, §4.4, `filters`);
4. subtract the robot's torque at equal angles on the same branch (§3.3, §5.6, `subtraction`), or at
   equal times if the settings ask for the (wrong, §5.6) comparison method;
5. energy lost per complete cycle (§5.7, Eq 10-12, `energy`), and the trial's centred loop (§6.2.3 note,
   `centring`) for the Bouc-Wen fit, which the caller runs (`models.bouc_wen`).

Then, over all trials: every cycle's energy in trial order, their summary, and the fit of the device's
elastic elements (§6.1, `element_fit`) when the configuration's device is given. Pure: arrays in,
dataclasses of arrays out.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from protocol_runner.analysis.centring import CentredLoop, centre
from protocol_runner.analysis.element_fit import ElementFit, fit_elements, not_applicable
from protocol_runner.analysis.energy import EnergySummary, energy_per_cycle, summarize_energy
from protocol_runner.analysis.filters import design_lowpass, filter_zero_phase_together
from protocol_runner.analysis.processing_settings import ProcessingSettings
from protocol_runner.analysis.subtraction import robot_torque_at_equal_angle, subtract_equal_time
from protocol_runner.analysis.transition import (
    TrialSegment,
    command_on_input_base,
    remove_transition,
)
from protocol_runner.analysis.validation import AnalysisError, FloatArray, as_signal, same_length


@dataclass(frozen=True)
class Recording:
    """One trial's recorded data, as archived under `trials/<n>/brace_on` or `brace_off`.

    `time_s`, `angle_deg`, `torque_nm` are on the input time base (1 kHz). `command_deg` is either on that
    same time base (`command_time_s=None`) or on its own output ticks `command_time_s` (100 Hz).
    """

    time_s: FloatArray
    angle_deg: FloatArray
    torque_nm: FloatArray
    command_deg: FloatArray
    command_time_s: FloatArray | None = None


@dataclass(frozen=True)
class TrialPair:
    """A brace-on trial and the brace-off trial run for it (same configuration, same trial number)."""

    brace_on: Recording
    brace_off: Recording
    trial: int = 1


@dataclass(frozen=True)
class ProcessedTrial:
    """One trial after processing (the archive's `trials/<n>/processed`)."""

    trial: int
    time_s: FloatArray  # brace-on input times from its transition point on
    angle_deg: FloatArray  # filtered brace-on angle
    brace_torque_nm: FloatArray  # filtered brace-on torque minus the robot's torque (equal angle/time)
    robot_torque_nm: FloatArray  # the brace-off torque that was subtracted, per sample
    transition_index_on: int
    transition_index_off: int
    coverage: float  # fraction of samples whose angle the brace-off branch curves covered (1.0 equal-time)
    energy_j: FloatArray  # energy lost per complete cycle of this trial
    centred: CentredLoop  # the loop centred per trial (§6.2.3), or uncentred when centring="none"


@dataclass(frozen=True)
class ConfigurationResult:
    """Everything `process_configuration` produces for one configuration."""

    trials: tuple[ProcessedTrial, ...]
    energy_loss_j: FloatArray  # one value per complete cycle over all trials, in trial order
    energy_cycle_trial: npt.NDArray[np.int64]  # the trial number of each energy_loss_j value
    energy: EnergySummary
    elements: ElementFit | None  # the elastic elements' fit; None when the device was not given
    settings: ProcessingSettings = field(repr=False)

    @property
    def centred_segments(self) -> tuple[tuple[FloatArray, FloatArray], ...]:
        """(angle_deg, torque_nm) of each trial's centred loop, in trial order: the Bouc-Wen fit's input."""
        return tuple((t.centred.angle_deg, t.centred.torque_nm) for t in self.trials)


def _segment(rec: Recording, settings: ProcessingSettings, label: str) -> TrialSegment:
    t = as_signal(f"{label} time_s", rec.time_s)
    angle = as_signal(f"{label} angle_deg", rec.angle_deg)
    torque = as_signal(f"{label} torque_nm", rec.torque_nm)
    same_length(**{f"{label}_time_s": t, f"{label}_angle_deg": angle, f"{label}_torque_nm": torque})
    if rec.command_time_s is None:
        command = as_signal(f"{label} command_deg", rec.command_deg)
        same_length(**{f"{label}_time_s": t, f"{label}_command_deg": command})
    else:
        command = command_on_input_base(rec.command_time_s, rec.command_deg, t, settings.command_resampling)
    try:
        return remove_transition(
            t,
            command,
            angle,
            torque,
            tolerance_deg=settings.transition_tolerance_deg,
            points=settings.transition_points,
        )
    except AnalysisError as exc:
        raise AnalysisError(f"{label}: {exc.message}") from None


def process_trial(pair: TrialPair, settings: ProcessingSettings) -> ProcessedTrial:
    """Steps 1-5 of the module docstring for one trial pair."""
    on = _segment(pair.brace_on, settings, f"trial {pair.trial} brace-on")
    off = _segment(pair.brace_off, settings, f"trial {pair.trial} brace-off")
    sos = design_lowpass(
        settings.filter_kind, settings.filter_order, settings.filter_cutoff, settings.chebyshev_ripple_db
    )
    angle_on, torque_on = filter_zero_phase_together(
        [on.angle_deg, on.torque_nm],
        sos,
        names=[f"trial {pair.trial} brace-on angle_deg", f"trial {pair.trial} brace-on torque_nm"],
    )
    angle_off, torque_off = filter_zero_phase_together(
        [off.angle_deg, off.torque_nm],
        sos,
        names=[f"trial {pair.trial} brace-off angle_deg", f"trial {pair.trial} brace-off torque_nm"],
    )
    if settings.subtraction == "equal_angle":
        try:
            robot, covered = robot_torque_at_equal_angle(
                angle_on,
                angle_off,
                torque_off,
                bin_width_deg=settings.bin_width_deg,
                reversal_deg=settings.reversal_deg,
                outside=settings.outside,
            )
        except AnalysisError as exc:
            raise AnalysisError(f"trial {pair.trial} brace-off: {exc.message}") from None
        coverage = float(np.mean(covered))
    else:
        robot = torque_on - subtract_equal_time(on.time_s, torque_on, off.time_s, torque_off)
        coverage = 1.0
    brace = torque_on - robot
    finite = np.isfinite(brace)
    if np.all(finite):
        energy = energy_per_cycle(
            angle_on, brace, hysteresis_deg=settings.cycle_hysteresis_deg, reference=settings.cycle_reference
        )
    else:
        # outside="nan": only complete cycles inside stretches where the brace torque is defined count.
        energy = _energy_of_covered(angle_on, brace, settings)
    kept = (angle_on[finite], brace[finite])
    loop = centre(*kept) if settings.centring == "trial_mean" else CentredLoop(*kept, 0.0, 0.0)
    return ProcessedTrial(
        trial=pair.trial,
        time_s=on.time_s,
        angle_deg=angle_on,
        brace_torque_nm=brace,
        robot_torque_nm=robot,
        transition_index_on=on.start_index,
        transition_index_off=off.start_index,
        coverage=coverage,
        energy_j=energy,
        centred=loop,
    )


def _energy_of_covered(angle: FloatArray, brace: FloatArray, settings: ProcessingSettings) -> FloatArray:
    """Energy of the complete cycles lying wholly in stretches where the brace torque is defined."""
    finite = np.isfinite(brace)
    edges = np.flatnonzero(np.diff(np.concatenate(([0], finite.astype(np.int8), [0]))))
    parts: list[FloatArray] = []
    for start, stop in zip(edges[0::2], edges[1::2], strict=True):
        if stop - start >= 3:
            parts.append(
                energy_per_cycle(
                    angle[start:stop],
                    brace[start:stop],
                    hysteresis_deg=settings.cycle_hysteresis_deg,
                    reference=settings.cycle_reference,
                )
            )
    return np.concatenate(parts) if parts else np.zeros(0, dtype=np.float64)


def process_configuration(
    trials: Sequence[TrialPair],
    settings: ProcessingSettings | None = None,
    *,
    device: Sequence[object] | None = None,
) -> ConfigurationResult:
    """Process every trial pair of one configuration and pool the results (thesis §3-§6.1, module
    docstring). `device` (the configuration's resolved elements: `models.elements.Element`s or
    ElementSetting-like objects) asks for the element fit, "not applicable" with the reason for a device
    with nothing to fit or a loop that cannot support one. Raises `AnalysisError` naming the trial when a
    step cannot be done.
    """
    settings = settings if settings is not None else ProcessingSettings()
    if not trials:
        raise AnalysisError("a configuration needs at least one trial pair to process")
    numbers = [p.trial for p in trials]
    if len(set(numbers)) != len(numbers):
        raise AnalysisError(f"trial numbers must be distinct, got {numbers}")
    processed = tuple(process_trial(pair, settings) for pair in trials)
    energy = np.concatenate([t.energy_j for t in processed])
    cycle_trial = np.concatenate([np.full(t.energy_j.shape[0], t.trial, dtype=np.int64) for t in processed])
    fit: ElementFit | None = None
    if device is not None:
        angle_all = np.concatenate([t.angle_deg for t in processed])
        brace_all = np.concatenate([t.brace_torque_nm for t in processed])
        keep = np.isfinite(brace_all)
        try:
            fit = fit_elements(
                angle_all[keep],
                brace_all[keep],
                device,
                target=settings.element_fit_target,
                reversal_deg=settings.reversal_deg,
            )
        except AnalysisError as exc:
            fit = not_applicable(exc.message, settings.element_fit_target)
    return ConfigurationResult(
        trials=processed,
        energy_loss_j=energy,
        energy_cycle_trial=cycle_trial,
        energy=summarize_energy(energy),
        elements=fit,
        settings=settings,
    )
