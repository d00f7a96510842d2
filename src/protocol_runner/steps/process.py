"""Processing step: one configuration's archived trials -> the device's own torque, energy, element fit.

Reads the trial units (never the rig), then `analysis.service.analyse_configuration` (without the
Bouc-Wen fit, which is the fit step's): transition removal (§3.3.1), zero-phase filtering (§3.2),
equal-angle subtraction of the brace-off torque (§3.3, §5.6), cycles and energy per cycle (Eq 10-12), the
fit of the device's elastic elements (§6.1), and the processed loops as stored.
"""

from __future__ import annotations

from ..analysis.pipeline import TrialPair
from ..analysis.service import analyse_configuration
from ..archive.paths import configuration_name, recording_path
from ..archive.results import processed_fill, read_recording
from ..protocol.plan_steps import ProcessStep
from ..protocol.processing import element_fit_enabled
from .context import StepContext, StepOutcome


def run(step: ProcessStep, ctx: StepContext) -> StepOutcome:
    name = configuration_name(step.configuration)
    pairs = []
    for n, (on_id, off_id) in enumerate(step.trials, start=1):
        with ctx.unit(on_id) as f_on, ctx.unit(off_id) as f_off:
            pairs.append(
                TrialPair(
                    read_recording(f_on[recording_path(step.configuration, n, "on")]),
                    read_recording(f_off[recording_path(step.configuration, n, "off")]),
                    trial=n,
                )
            )
    device = ctx.trial_step(step.configuration).settings.device
    analysis = analyse_configuration(
        pairs, ctx.processing, device=device if element_fit_enabled(ctx.loaded) else None
    )
    energy = analysis.processed.energy
    summary = (
        f"{energy.n} cycles, energy {energy.mean_j:.2f} +- {energy.std_j:.2f} J"
        if energy.n
        else "no complete cycle"
    )
    return StepOutcome(processed_fill(name, analysis, ctx.processing), summary)
